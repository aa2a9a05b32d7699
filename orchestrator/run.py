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
import json
import multiprocessing
import os
import shutil
import signal
import threading
import time as _time
import warnings
from pathlib import Path

import pyarrow.parquet as pq

from .cosim import (
    DivergenceError,
    EarlyEndWarning,
    SaturationWarning,
    Simulation,
    SimulationError,
    prepare,
)
from .files import atomic_write
from .linearcheck import UnstableLoopWarning, linear_verdict
from .progress import ProgressBar
from .results import (
    RunResult,
    arrow_table,
    package_versions,
    write_mat,
    write_metadata,
    write_table,
)
from .scenario import load_scenario

__all__ = ["run_scenario", "OutputError", "RecordTooLargeError", "check_record_size",
           "PARTIAL_DIR", "PREVIOUS_DIR", "FLUSH_SECONDS"]


#: Folder, inside ``out_dir``, that holds the rows flushed during a run.
PARTIAL_DIR = "results.partial"
#: Seconds between flushes of recorded rows to ``PARTIAL_DIR`` (env JITTERFMU_FLUSH_SECONDS).
FLUSH_SECONDS = 5.0


#: Folder, inside ``out_dir``, that keeps the complete result a later run found there
#: until that run completes too.
PREVIOUS_DIR = "previous"
#: Statuses of a run that completed (its results replace the previous ones); an
#: ``unstable`` run ran to its end held at a rail or limit (:data:`HELD_FRACTION`).
FINISHED = ("ok", "terminated", "unstable")
#: A run with a rail or limit flag (``sat_*``) set for more than this fraction of it ends
#: with status ``unstable``: its loop is held by the limits, not the loop designed.
HELD_FRACTION = 0.10
RESULT_FILES = ("results.parquet", "results.csv", "results.mat")
#: Formats of the results file: Parquet, CSV (``name [unit]`` header), MATLAB v5.
FORMATS = ("parquet", "csv", "mat")


class OutputError(OSError):
    """The output folder of a run cannot be used (not writable, busy, or holding rows
    of an unfinished run)."""


class RecordTooLargeError(MemoryError):
    """The record of a run would not fit in the memory available."""


def _partial_rows(folder: Path) -> int:
    """Rows in the complete Parquet parts of ``folder`` (0 if none)."""
    rows = 0
    for part in sorted(folder.glob("part-*.parquet")) if folder.is_dir() else ():
        try:
            rows += pq.ParquetFile(part).metadata.num_rows
        except Exception:  # a part cut by the kill: not rows anyone can read
            continue
    return rows


def _finished_result(folder: Path) -> list:
    """Names of a complete result in ``folder`` (``run.json`` says it finished)."""
    try:
        meta = json.loads((folder / "run.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    if not isinstance(meta, dict) or meta.get("status") not in FINISHED:
        return []
    names = [n for n in RESULT_FILES if (folder / n).is_file()]
    return [*names, "run.json"] if names else []


def _available_memory() -> int | None:
    """Bytes of memory available to a new allocation (Linux ``MemAvailable``), or None."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_record_size(plan, available=None) -> int:
    """Bytes a run's record needs; RecordTooLargeError if it cannot fit in memory.

    The record (rows times recorded variables, 8 bytes each) is held twice at the end
    of a run: as recorded and as the table written.

    Parameters
    ----------
    plan : Plan
    available : int, optional
        Bytes available (default: what the system reports).

    Returns
    -------
    int
        Bytes needed.
    """
    tb = plan.timebase
    rows = tb.n_ticks // tb.output_ticks + 1
    cols = len(plan.scenario.record) + 1
    need = 2 * 8 * rows * cols
    available = _available_memory() if available is None else available
    if available is not None and need > available:
        interval = float(tb.base * tb.output_ticks)
        raise RecordTooLargeError(
            f"the record of this run needs {need / 2**30:.1f} GiB ({rows:,} rows of "
            f"{cols} columns, held twice) and {available / 2**30:.1f} GiB of memory is "
            f"available; raise experiment.output_interval (now {interval!r} s), shorten "
            "the stop time, or record fewer variables")
    return need


class _Interrupted(Exception):
    """SIGINT or SIGTERM arrived during a run (raised from the master's own code)."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum


class _OutputFolder:
    """A locked run folder: ``run.json`` says ``running`` from the first step on, rows are
    flushed to ``results.partial/part-NNNNNN.parquet`` (each file complete, so a killed
    run leaves readable rows), and the final results replace the old ones atomically."""

    def __init__(self, path: Path, fmt: str = "parquet", overwrite: bool = False,
                 units: dict | None = None):
        self.path = path
        self.fmt = fmt
        self.units = units or {}
        self.finished = False
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
        try:
            self._keep_earlier_results(overwrite)
        except BaseException:
            self.close()
            raise

    def _keep_earlier_results(self, overwrite: bool) -> None:
        """Refuse to drop a killed run's rows; move a complete result to ``previous/``."""
        self._mark_killed()
        rows = _partial_rows(self.partial)
        if rows and not overwrite:
            raise OutputError(
                f"output folder {str(self.path)!r} holds {rows:,} rows of a run that did not "
                f"finish ({PARTIAL_DIR}/, readable with orchestrator.read_table); move them "
                "away, choose another --out, or pass --overwrite to discard them")
        shutil.rmtree(self.partial, ignore_errors=True)
        old = _finished_result(self.path)
        if old:
            previous = self.path / PREVIOUS_DIR
            shutil.rmtree(previous, ignore_errors=True)
            previous.mkdir()
            for name in old:
                os.replace(self.path / name, previous / name)

    def _mark_killed(self) -> None:
        """A ``run.json`` that says ``running`` while this process holds the folder's lock
        was left by a run that was killed (SIGKILL, power loss): it says so from now on."""
        path = self.path / "run.json"
        try:
            meta = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return
        if isinstance(meta, dict) and meta.get("status") == "running":
            write_metadata(dict(meta, status="killed", error=(
                "the process writing this run ended before it finished (killed); the rows "
                f"it flushed are in {PARTIAL_DIR}/")), path)

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
        atomic_write(final, lambda tmp: pq.write_table(arrow_table(cols, self.units), tmp))
        self.parts += 1
        self.flushed = rows

    def finish(self, table: dict, meta: dict) -> None:
        """Replace the results and ``run.json`` atomically, then drop the partial rows.

        A run that did not complete keeps the complete result found before it in
        ``previous/`` (and says so in ``run.json``); a complete run supersedes it.
        """
        complete = meta.get("status") in FINISHED
        if not complete and (self.path / PREVIOUS_DIR / "run.json").is_file():
            meta["previous_result"] = PREVIOUS_DIR
        for name in RESULT_FILES:  # the other format of an earlier run
            if name != self.results_name and (self.path / name).exists():
                os.unlink(self.path / name)
        if self.fmt == "mat":
            write_mat(table, self.path / self.results_name, self.units)
        else:
            write_table(table, self.path / self.results_name, csv=self.fmt == "csv",
                        units=self.units)
        write_metadata(meta, self.path / "run.json")
        shutil.rmtree(self.partial, ignore_errors=True)
        self.finished = True
        if complete:   # the new complete result supersedes any kept one
            shutil.rmtree(self.path / PREVIOUS_DIR, ignore_errors=True)

    @property
    def results_name(self) -> str:
        return f"results.{self.fmt}"

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
                 quiet=True, csv=False, fmu_dir=None, fmu_kind=None, overwrite=False,
                 fmt=None):
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
        ``ok``, ``error``, ``diverged``, ``terminated`` or ``interrupted``) replace the
        earlier ones at the end, atomically.
    stop_time : float, optional
        Overrides ``experiment.stop`` (s).
    overrides : dict or iterable of str, optional
        Start values, ``{"inst.var": value}`` or ``["inst.var=value", ...]``.
    algorithm : {"gauss-seidel", "jacobi"}, optional
        Overrides ``experiment.algorithm``.
    quiet : bool
        No progress bar.
    csv : bool
        Write CSV instead of Parquet (the same as ``fmt="csv"``).
    fmu_dir : path-like, optional
        Extra folder searched first for FMU names.
    fmu_kind : {"native", "python"}, optional
        Overrides ``experiment.fmu_kind``: which build of the suite's FMUs to run.
    fmt : {"parquet", "csv", "mat"}, optional
        Format of the results file (default Parquet): ``results.parquet`` (units in the
        field metadata), ``results.csv`` (header ``name [unit]``) or ``results.mat``
        (MATLAB v5: a struct per instance, and ``units``).
    overwrite : bool
        Discard the rows a killed run left in ``out_dir/results.partial/`` (without it
        such a folder is refused).  A complete earlier result is never lost: it moves
        to ``out_dir/previous/`` for the run and is dropped only when the new run
        completes.

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

        A value that leaves the range its FMU declares (or grows beyond
        :data:`orchestrator.cosim.bus.RUNAWAY`) ends the run with status ``diverged``
        and a DivergenceError.  Saturation flags (``sat_*`` outputs) set during the run
        are summarised in ``metadata["saturation"]`` and a :class:`SaturationWarning`.

    Raises
    ------
    OutputError
        Before anything runs, if `out_dir` is not writable, in use by another run, or
        holds the rows of an unfinished run (see `overwrite`).
    RecordTooLargeError
        Before anything runs, if the record cannot fit in the memory available.
    """
    wall0 = _time.perf_counter()
    fmt = "csv" if csv else (fmt or "parquet")
    if fmt not in FORMATS:
        raise ValueError(f"results format {fmt!r} is not one of {', '.join(FORMATS)}")
    sc = load_scenario(scenario)
    sc = sc.with_overrides(overrides).with_experiment(stop=stop_time, algorithm=algorithm,
                                                      fmu_kind=fmu_kind)
    plan = prepare(sc, fmu_dir)
    check_record_size(plan)
    units = {"time": "s"}
    for ref in sc.record:
        inst, _, var = ref.partition(".")
        units[ref] = plan.fmus[inst].variables[var].unit or ""
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
        "units": units,
        "format": fmt,
        "versions": package_versions(),
    }
    folder = (_OutputFolder(Path(out_dir), fmt, overwrite, units) if out_dir is not None
              else None)
    try:
        if folder is not None:
            folder.start(meta)
        return _run_plan(plan, meta, folder, quiet, wall0)
    except BaseException as exc:
        # whatever ends the process here, run.json must not say "running" behind it
        if folder is not None and not folder.finished:
            meta.update(status="error", error=str(exc) or type(exc).__name__,
                        wall_time_s=_time.perf_counter() - wall0)
            try:
                folder.finish({"time": []}, meta)
            except OSError:
                pass
        raise
    finally:
        if folder is not None:
            folder.close()


def _report_saturation(sim, meta) -> None:
    """``meta["saturation"]`` and one SaturationWarning naming what saturated, how long."""
    spans = sim.saturation()
    if not spans:
        return
    tb = sim.plan.timebase
    length = float(tb.base * max(sim.tick, 1))
    meta["saturation"] = [{"instance": i, "flag": f, "seconds": sec, "first": first,
                           "fraction": sec / length} for i, f, sec, first in spans]
    parts = [f"{i}.{f} {sec:.4g} s ({100 * sec / length:.0f} % of the run, from "
             f"t = {first:.6g} s)" for i, f, sec, first in spans]
    warnings.warn("saturated during the run: " + "; ".join(parts) + ": a loop at a rail or "
                  "limit is not the linear loop it was designed as", SaturationWarning,
                  stacklevel=3)
    i, f, sec, first = max(spans, key=lambda x: x[2])
    if meta.get("status") == "ok" and sec > HELD_FRACTION * length:
        meta["status"] = "unstable"
        meta["unstable"] = {
            "instance": i, "flag": f, "seconds": sec, "first": first,
            "message": f"the loop through {i} sat at its {f[4:]} limit ({i}.{f}) for "
                       f"{sec:.4g} s, {100 * sec / length:.0f} % of the run from t = "
                       f"{first:.6g} s: held by its limits, not the loop designed (status "
                       "unstable); lower the gains or check the loop's stability with "
                       "jitterfmu analyze"}


def _run_plan(plan, meta, folder, quiet, wall0):
    """Initialise, step, write; the body of :func:`run_scenario`."""
    sc = plan.scenario
    sim = Simulation(plan)  # allocates the record (its size was checked)
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
        if isinstance(exc, DivergenceError):
            meta["diverged"] = {"instance": exc.instance, "time": exc.time}
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
    status = ("interrupted" if interrupted is not None
              else "diverged" if isinstance(error, DivergenceError)
              else "error" if error is not None
              else "terminated" if sim.terminated else "ok")
    meta.update(
        status=status,
        error=None if error is None else str(error),
        rows=len(table["time"]),
        wall_time_s=_time.perf_counter() - wall0,
    )
    _report_saturation(sim, meta)
    if meta["status"] == "ok":   # a loop the linear engine finds unstable is no result
        meta["linear_check"], unstable = linear_verdict(plan)
        if unstable:
            meta.update(status="unstable", unstable=unstable)
            warnings.warn(unstable["message"], UnstableLoopWarning, stacklevel=3)
    if error is None and sim.terminated:
        inst, t_end, message = sim.terminated
        meta["terminated"] = {"instance": inst, "time": t_end, "message": message,
                              "last_successful_time": sim.last_successful_time}
        warnings.warn(f"instance {inst!r} ended the run at t = {t_end!r} s (fmi2Terminated)"
                      + (f": {' '.join(message.split())}" if message else "")
                      + f"; {meta['rows']} rows recorded", EarlyEndWarning, stacklevel=3)
    path = None
    if folder is not None:
        path = folder.path
        meta["wall_time_s"] = _time.perf_counter() - wall0
        folder.finish(table, meta)
    result = RunResult(table, meta, path)
    if error is not None and meta.get("previous_result"):
        error.args = (f"{error}; the complete result found in the folder is kept in "
                      f"{path / PREVIOUS_DIR}",)
    if interrupted == signal.SIGINT:
        raise KeyboardInterrupt(str(error))
    if error is not None:
        error.result = result
        raise error
    return result
