"""Run a scenario: load, check, simulate, and write the results as they come.

:func:`run_scenario` is the library's one call for a run.  It locks the output folder,
says ``running`` in ``run.json`` before the first step, flushes the rows recorded so
far to ``results.partial/`` every few seconds (complete Parquet files, so a killed run
keeps them), turns SIGINT/SIGTERM into a clean end between steps, and replaces the
results and ``run.json`` atomically at the end.  The engine itself is
:mod:`orchestrator.cosim`.
"""

from __future__ import annotations

import fcntl
import multiprocessing
import os
import shutil
import signal
import threading
import time as _time
import warnings
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from .cosim import EarlyEndWarning, Simulation, SimulationError, prepare
from .files import atomic_write
from .progress import ProgressBar
from .results import RunResult, package_versions, write_metadata, write_table
from .scenario import load_scenario

__all__ = ["run_scenario", "OutputError", "PARTIAL_DIR", "FLUSH_SECONDS"]


#: Folder, inside ``out_dir``, that holds the rows flushed during a run.
PARTIAL_DIR = "results.partial"
#: Seconds between flushes of recorded rows to ``PARTIAL_DIR`` (env JITTERFMU_FLUSH_SECONDS).
FLUSH_SECONDS = 5.0


class OutputError(OSError):
    """The output folder of a run cannot be used (not writable, or busy)."""


class _Interrupted(Exception):
    """SIGINT or SIGTERM arrived during a run (raised from the master's own code)."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum


class _OutputFolder:
    """A locked run folder: ``run.json`` says ``running`` from the first step on, rows are
    flushed to ``results.partial/part-NNNNNN.parquet`` (each file complete, so a killed
    run leaves readable rows), and the final results replace the old ones atomically."""

    def __init__(self, path: Path, csv: bool):
        self.path = path
        self.csv = csv
        self.partial = path / PARTIAL_DIR
        self.flushed = 0
        self.parts = 0
        self.last_flush = _time.monotonic()
        self.every = float(os.environ.get("JITTERFMU_FLUSH_SECONDS", FLUSH_SECONDS))
        try:
            path.mkdir(parents=True, exist_ok=True)
            self._lock = open(path / ".jitterfmu.lock", "a+")
        except OSError as exc:
            raise OutputError(f"output folder {str(path)!r} is not writable: "
                              f"{exc.strerror}; choose another --out") from None
        try:
            fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self._lock.close()
            raise OutputError(f"output folder {str(path)!r} is in use by another run or "
                              "campaign; wait for it or choose another --out") from None
        shutil.rmtree(self.partial, ignore_errors=True)  # rows of an earlier killed run

    def start(self, meta: dict) -> None:
        """Write ``run.json`` with status ``running`` (proves the folder is writable)."""
        try:
            write_metadata(dict(meta, status="running", rows=0, error=None,
                                partial_results=PARTIAL_DIR), self.path / "run.json")
            self.partial.mkdir(exist_ok=True)
        except OSError as exc:
            raise OutputError(f"output folder {str(self.path)!r} is not writable: "
                              f"{exc.strerror}; choose another --out") from None

    def maybe_flush(self, sim) -> None:
        if _time.monotonic() - self.last_flush >= self.every:
            self.flush(sim)

    def flush(self, sim) -> None:
        """Write the rows recorded since the last flush as one complete Parquet file."""
        self.last_flush = _time.monotonic()
        rows = sim.rows
        if rows <= self.flushed:
            return
        cols = {"time": sim.times[self.flushed:rows]}
        for j, ref in enumerate(sim.plan.scenario.record):
            cols[ref] = sim.rec[self.flushed:rows, j]
        final = self.partial / f"part-{self.parts:06d}.parquet"
        atomic_write(final, lambda tmp: pq.write_table(pa.table(cols), tmp))
        self.parts += 1
        self.flushed = rows

    def finish(self, table: dict, meta: dict) -> None:
        """Replace the results and ``run.json`` atomically, then drop the partial rows."""
        write_table(table, self.path / ("results.csv" if self.csv else "results.parquet"),
                    csv=self.csv)
        write_metadata(meta, self.path / "run.json")
        shutil.rmtree(self.partial, ignore_errors=True)

    def close(self) -> None:
        self._lock.close()  # releases the lock


class _SignalGuard:
    """Turn SIGINT and SIGTERM into a flag the run loop checks (main thread only).

    The flag is read between steps, in the master's own code, so the exception never
    lands inside a Python FMU's step.  Nothing is installed in a worker process or a
    thread, where the host owns the signals.
    """

    def __init__(self):
        self.signum = None
        self.previous = {}
        if (threading.current_thread() is not threading.main_thread()
                or multiprocessing.parent_process() is not None):
            return
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                self.previous[sig] = signal.signal(sig, self._handle)
            except (ValueError, OSError):  # pragma: no cover - not the main interpreter
                pass

    def _handle(self, signum, frame):
        self.signum = signum

    def check(self) -> None:
        if self.signum is not None:
            raise _Interrupted(self.signum)

    def restore(self) -> None:
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)
        self.previous = {}


def run_scenario(scenario, out_dir=None, *, stop_time=None, overrides=None, algorithm=None,
                 quiet=True, csv=False, fmu_dir=None, fmu_kind=None):
    """Run a scenario and return (and optionally write) its recorded results.

    Parameters
    ----------
    scenario : path-like, dict or Scenario
        A TOML file, an SSP archive, the TOML layout as a dict, or a Scenario.
    out_dir : path-like, optional
        Folder for ``results.parquet`` (or ``results.csv``) and ``run.json``.  It is
        locked for the run (a second run into it fails at once), ``run.json`` says
        ``running`` from before the first step, and the rows recorded so far are
        flushed every :data:`FLUSH_SECONDS` to ``results.partial/`` (complete Parquet
        files: a killed run keeps them).  The final results and ``run.json`` (status
        ``ok``, ``error``, ``terminated`` or ``interrupted``) replace the earlier ones
        at the end, atomically.
    stop_time : float, optional
        Overrides ``experiment.stop`` (s).
    overrides : dict or iterable of str, optional
        Start values, ``{"inst.var": value}`` or ``["inst.var=value", ...]``.
    algorithm : {"gauss-seidel", "jacobi"}, optional
        Overrides ``experiment.algorithm``.
    quiet : bool
        No progress bar.
    csv : bool
        Write CSV instead of Parquet.
    fmu_dir : path-like, optional
        Extra folder searched first for FMU names.
    fmu_kind : {"native", "python"}, optional
        Overrides ``experiment.fmu_kind``: which build of the suite's FMUs to run.

    Returns
    -------
    RunResult
        ``table`` (dict of arrays keyed ``time`` and ``instance.variable``), ``metadata``
        and ``path``.  On a failure during the run, SimulationError is raised with the
        partial RunResult (already written when `out_dir` is given) as ``exc.result``.
        An FMU that asks to terminate (fmi2Discard with fmi2Terminated true) ends the
        run normally: status ``terminated``, the rows up to that point, and an
        :class:`EarlyEndWarning`.  SIGTERM ends the run with status ``interrupted``
        and a SimulationError, SIGINT the same with KeyboardInterrupt, both after
        writing the rows so far.

    Raises
    ------
    OutputError
        Before anything runs, if `out_dir` is not writable or in use by another run.
    """
    wall0 = _time.perf_counter()
    sc = load_scenario(scenario)
    sc = sc.with_overrides(overrides).with_experiment(stop=stop_time, algorithm=algorithm,
                                                      fmu_kind=fmu_kind)
    plan = prepare(sc, fmu_dir)
    meta = {
        "scenario": sc.source,
        "scenario_sha256": sc.digest(),
        "algorithm": sc.experiment.algorithm,
        "fmu_kind": sc.experiment.fmu_kind,
        "start": float(sc.experiment.start),
        "stop": float(sc.experiment.stop),
        "base_step": str(plan.timebase.base),
        "n_ticks": plan.timebase.n_ticks,
        "fmus": {i.name: {"fmu": str(plan.fmus[i.name].path),
                          "sha256": plan.fmus[i.name].sha256,
                          "period": str(i.period)} for i in sc.instances},
        "loops": [l.describe() for l in plan.loops],
        "unconnected_inputs": list(plan.unconnected),
        "versions": package_versions(),
    }
    folder = _OutputFolder(Path(out_dir), csv) if out_dir is not None else None
    try:
        if folder is not None:
            folder.start(meta)
        return _run_plan(plan, meta, folder, quiet, wall0)
    finally:
        if folder is not None:
            folder.close()


def _run_plan(plan, meta, folder, quiet, wall0):
    """Initialise, step, write; the body of :func:`run_scenario`."""
    sc = plan.scenario
    sim = Simulation(plan)
    progress = ProgressBar(1.0, f"jitterfmu run {Path(sc.source).name}",
                           enabled=False if quiet else None, delay=3.0)
    guard = _SignalGuard()

    def on_progress(fraction):
        progress(fraction)
        guard.check()
        if folder is not None:
            folder.maybe_flush(sim)

    error = interrupted = None
    try:
        guard.check()
        sim.initialize()
        sim.run(on_progress)
    except SimulationError as exc:
        error = exc
    except _Interrupted as exc:
        interrupted = exc.signum
        name = signal.Signals(exc.signum).name
        error = SimulationError(f"run interrupted by {name} at t = {sim._now()!r} s", None,
                                sim._now())
    except Exception as exc:  # an unexpected failure still leaves the rows written
        error = SimulationError(f"run failed at t = {sim._now()!r} s: {exc}", None,
                                sim._now())
        error.__cause__ = exc
    finally:
        guard.restore()
        progress.close()
        sim.close()
    table = sim.table()
    status = ("interrupted" if interrupted is not None else "error" if error is not None
              else "terminated" if sim.terminated else "ok")
    meta.update(
        status=status,
        error=None if error is None else str(error),
        rows=len(table["time"]),
        wall_time_s=_time.perf_counter() - wall0,
    )
    if error is None and sim.terminated:
        inst, t_end, message = sim.terminated
        meta["terminated"] = {"instance": inst, "time": t_end, "message": message}
        warnings.warn(f"instance {inst!r} ended the run at t = {t_end!r} s (fmi2Terminated)"
                      + (f": {' '.join(message.split())}" if message else "")
                      + f"; {meta['rows']} rows recorded", EarlyEndWarning, stacklevel=3)
    path = None
    if folder is not None:
        path = folder.path
        meta["wall_time_s"] = _time.perf_counter() - wall0
        folder.finish(table, meta)
    result = RunResult(table, meta, path)
    if interrupted == signal.SIGINT:
        raise KeyboardInterrupt(str(error))
    if error is not None:
        error.result = result
        raise error
    return result
