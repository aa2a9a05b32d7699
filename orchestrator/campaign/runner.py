"""One case: run it, compute its jitter metrics from the table in memory, publish its folder.

A *runner* is any callable ``runner(scenario_dict, out_dir)`` that runs a case's scenario
and writes ``out_dir/results.parquet``; it returns a :class:`~orchestrator.results.RunResult`
(the table in memory, as :class:`MasterRunner` does) or the path of the results file
(then read once).  :func:`execute_case` computes the metrics from that table and renames the
case's temporary folder to ``cases/KEY`` only when everything is written.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import time
import traceback
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pyarrow as pa

from .. import metrics as M
from ..cosim import find_fmu, read_fmu_info
from ..cosim.plan import coerce
from ..results import RunResult, read_columns, rows_table
from ..run import run_scenario
from ..scenario import ScenarioError, closest, scenario_from_dict
from .cases import Case
from .store import (
    CASE_FILES,
    METRIC_SCHEMA,
    METRICS_FILE,
    RESULTS_FILE,
    STATUS_FILE,
    file_record,
    not_a_folder,
    publish,
    temporary_folder,
    write_json,
    write_table,
)

# Names the time column of a results table may have.
_TIME_COLUMNS = ("time", "t", "time_s")


class MasterRunner:
    """Run a case with the co-simulation master.

    Parameters
    ----------
    base_dir : path-like
        Folder against which the FMU names of a case's scenario are resolved (the base
        scenario's folder), as :func:`orchestrator.cosim.find_fmu` does for a scenario file.
    fmu_dir : path-like, optional
        Extra folder searched first for FMU names.
    fmu_kind : {"native", "python"}, optional
        Overrides the cases' ``experiment.fmu_kind`` (which build of the suite's FMUs).

    Notes
    -----
    Picklable, so it runs in pool and Dask workers.  :meth:`fingerprint` returns the
    SHA-256 of every FMU file a scenario uses, so rebuilt FMUs change the case keys; a
    file is read once for all the cases that use it, and again only when it changes.
    """

    def __init__(self, base_dir=None, fmu_dir=None, fmu_kind=None):
        self.base_dir = Path(base_dir or Path.cwd()).resolve()
        self.fmu_dir = None if fmu_dir is None else Path(fmu_dir).resolve()
        self.fmu_kind = fmu_kind
        self._fingerprints = {}
        self._parsed = {}
        self._paths = {}

    def __getstate__(self):
        # the caches are this process's; a worker builds its own
        return {**self.__dict__, "_parsed": {}, "_paths": {}}

    def _scenario(self, scenario: dict):
        # a campaign asks for the same case scenario several times (key, overrides,
        # run): parsed once; the key is order-sensitive, as the scenario is
        key = json.dumps(scenario, default=str)
        sc = self._parsed.get(key)
        if sc is None:
            sc = scenario_from_dict(scenario, self.base_dir, source="<campaign case>")
            sc = sc.with_experiment(fmu_kind=self.fmu_kind)
            if len(self._parsed) >= 64:
                self._parsed.clear()
            self._parsed[key] = sc
        return sc

    def _find_fmu(self, name: str, sc) -> Path:
        """:func:`find_fmu`, remembered per name while the file found is still there."""
        key = (name, sc.base_dir, sc.experiment.fmu_kind)
        path = self._paths.get(key)
        if path is None or not path.is_file():
            path = self._paths[key] = find_fmu(name, sc, self.fmu_dir)
        return path

    def fingerprint(self, scenario: dict) -> str:
        """SHA-256 over the FMU files the scenario uses ("missing" for absent ones).

        Cases of a campaign differ in parameters only, so their FMU files are the same:
        the digest is kept per set of (instance, FMU name, file and its stat), and a
        file that changes (inode, size, modification or change time) is read again.
        """
        sc = self._scenario(scenario)
        files = []
        for inst in sorted(sc.instances, key=lambda i: i.name):
            try:
                path = self._find_fmu(inst.fmu, sc)
            except ValueError:
                path = None
            files.append((inst.name, inst.fmu, path))
        identity = tuple((name, fmu, None if path is None else (str(path), _stat(path)))
                         for name, fmu, path in files)
        if identity not in self._fingerprints:
            self._fingerprints[identity] = _fmu_digest(files)
        return self._fingerprints[identity]

    def override_problem(self, scenario: dict, ref: str, values=()) -> str | None:
        """Why a case cannot set ``ref`` (``instance.variable``); None if it can.

        The variable must be a parameter or an input of the instance's FMU and each
        value one of its type (as the master checks each run), so a misspelt override
        or a wrong value fails before any case runs rather than in every one.  An FMU that cannot be found or read is left to the
        cases, which say so.

        Parameters
        ----------
        scenario : dict
            A case's scenario data (the TOML layout).
        ref : str
            ``"instance.variable"``.
        values : sequence
            The values the campaign gives it (e.g. a sweep's points).

        Returns
        -------
        str or None
            One sentence, or None.
        """
        sc = self._scenario(scenario)
        inst, var = ref.split(".", 1)
        info = self._instance_info(sc, inst)
        if info is None:
            return None
        v = info.variables.get(var)
        if v is None:
            return (f"FMU {info.path.name} has no variable {var!r}"
                    f"{closest(var, info.variables)}")
        if v.causality not in ("parameter", "input") or v.variability == "constant":
            return (f"{ref} is a {v.variability} {v.causality}; only parameters and inputs "
                    "can be set")
        for value in values:
            try:
                coerce(value, v, ref)
            except ScenarioError as exc:
                return str(exc)
        return None

    def _instance_info(self, sc, inst: str):
        """The FMU information of instance ``inst`` of ``sc``; None when there is no such
        instance or its FMU cannot be found or read (left to the cases, which say so)."""
        fmu = next((i.fmu for i in sc.instances if i.name == inst), None)
        if fmu is None:
            return None
        try:
            return read_fmu_info(self._find_fmu(fmu, sc))
        except (ScenarioError, ValueError, OSError):
            return None

    def unit_of(self, scenario: dict, ref: str) -> str:
        """The unit the FMU declares for ``ref``; ``""`` when it declares none or the
        FMU cannot be read.

        Parameters
        ----------
        scenario, ref : dict, str
            A case's scenario data (the TOML layout) and ``"instance.variable"``.
        """
        inst, _, var = ref.partition(".")
        info = self._instance_info(self._scenario(scenario), inst)
        v = info.variables.get(var) if info is not None else None
        return (v.unit or "") if v is not None else ""

    def output_problem(self, scenario: dict, ref: str, recorded: bool = True) -> str | None:
        """Why a case's record cannot give ``ref`` (an instrument's axis); None if it can.

        The instance must be in the scenario, the variable in its FMU and the reference
        in ``[record] variables``, so a misspelt instrument variable fails before any
        case runs, with the closest name, rather than in every case after its run.  An
        FMU that cannot be found or read is left to the cases, which say so.

        Parameters
        ----------
        scenario : dict
            A case's scenario data (the TOML layout).
        ref : str
            ``"instance.variable"``.
        recorded : bool
            It must be in ``[record] variables`` too (the cases' records; a wheel sweep
            computes its instruments' angles whatever the record).

        Returns
        -------
        str or None
            One sentence, or None.
        """
        sc = self._scenario(scenario)
        inst, _, var = ref.partition(".")
        names = [i.name for i in sc.instances]
        if not var:
            return f"{ref!r} must have the form 'instance.variable'"
        if inst not in names:
            return (f"{ref!r} names instance {inst!r}, which the base scenario does not "
                    f"have{closest(inst, names)}")
        info = self._instance_info(sc, inst)
        if info is None:
            return None
        if var not in info.variables:
            return (f"FMU {info.path.name} of instance {inst!r} has no variable {var!r}"
                    f"{closest(var, info.variables)}")
        if recorded and ref not in sc.record:
            return (f"{ref} is not recorded; add it to [record] variables of the base "
                    "scenario")
        return None

    def __call__(self, scenario: dict, out_dir) -> RunResult:
        """Run a case's scenario into ``out_dir``.

        Parameters
        ----------
        scenario : dict
            Scenario data (the TOML layout).
        out_dir : path-like
            Folder for ``results.parquet`` and ``run.json``.

        Returns
        -------
        RunResult
            The recorded table in memory, its metadata and ``out_dir``.
        """
        return run_scenario(self._scenario(scenario), out_dir, quiet=True, fmu_dir=self.fmu_dir)


def _stat(path: Path) -> tuple:
    st = os.stat(path)
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns


def _fmu_digest(files) -> str:
    """SHA-256 over ``name:fmu:`` and the bytes (or ``missing``) of each instance's FMU."""
    h = hashlib.sha256()
    for name, fmu, path in files:
        h.update(f"{name}:{fmu}:".encode())
        if path is None:
            h.update(b"missing")
            continue
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
    return h.hexdigest()


def case_metrics(t, columns: Mapping, instruments: Mapping, metrics, skip: float = 0.0):
    """Jitter metrics of one case's recorded LOS angles.

    Parameters
    ----------
    t : array_like, shape (n_samples,)
        Time (s), uniformly spaced.
    columns : mapping of str to array_like, shape (n_samples,)
        Recorded variables by name (LOS angles in rad).
    instruments : mapping
        ``{instrument: {axis: variable}}``.
    metrics : sequence of (str, float or None)
        ``(kind, window)`` pairs (window or lag in s).
    skip : float
        Transient dropped from the start (s).

    Returns
    -------
    rows : list of dict
        ``instrument, axis, metric, window, value`` with value in rad.
    """
    t = np.asarray(t, dtype=float)
    if t.size < 2:
        raise ValueError(f"results hold {t.size} time sample(s); expected at least 2")
    d = np.diff(t)
    dt = float(np.median(d))
    if not np.allclose(d, dt, rtol=1e-6, atol=1e-12):
        raise ValueError("results time column is not uniformly spaced; "
                         "expected one output interval")
    keep = t >= M.skip_start(t[0], skip, dt)
    rows = []
    for inst, axes in instruments.items():
        for axis, var in axes.items():
            if var not in columns:
                raise KeyError(
                    f"recorded variable {var!r} for {inst}/{axis} is not in the results; "
                    "add it to [record] variables of the scenario"
                )
            x = np.asarray(columns[var], dtype=float)[keep]
            for (kind, w), v in zip(metrics, M.metric_values(x, dt, metrics)):
                rows.append(dict(instrument=inst, axis=axis, metric=kind, window=w,
                                 value=float(v)))
    return rows


def _metrics_table(table: Mapping, instruments: Mapping, metrics, skip: float) -> pa.Table:
    """:func:`case_metrics` of a results table, as the rows of ``metrics.parquet``."""
    names = list(table)
    tcol = next((c for c in _TIME_COLUMNS if c in names), None)
    if tcol is None:
        raise ValueError(f"results file {RESULTS_FILE} has no 'time' column (has {names[:5]})")
    columns = {c: table[c] for c in names if c != tcol}
    rows = case_metrics(table[tcol], columns, instruments, metrics, skip)
    return rows_table(rows, METRIC_SCHEMA)


class CampaignInterrupted(BaseException):
    """SIGTERM or SIGINT stopped a campaign running in this process.

    A :class:`BaseException`, like :class:`KeyboardInterrupt`, so that no ``except
    Exception`` records the case in flight as failed and goes on with the next one.

    Attributes
    ----------
    signum : int
        The signal.
    """

    def __init__(self, signum: int, message: str = ""):
        super().__init__(message or f"interrupted by {signal.Signals(signum).name}")
        self.signum = signum


def execute_case(case: Case, runner: Callable, cases_dir, instruments, metrics, skip) -> dict:
    """Run one case and publish its folder atomically; never raises for case errors.

    The runner works in ``cases_dir/.tmp-KEY-RANDOM``; the folder is renamed to
    ``cases_dir/KEY`` when results, metrics and ``case.json`` are written.  A plain
    file at ``cases_dir/KEY`` fails the case, in one sentence, without running it.

    Parameters
    ----------
    case : Case
    runner : callable
        ``runner(scenario_dict, out_dir)`` returning a RunResult or the path of
        ``results.parquet``.
    cases_dir : path-like
        The campaign's ``cases`` folder.
    instruments : mapping
        ``{instrument: {axis: variable}}``; recorded LOS angles in rad.
    metrics : sequence of (str, float or None)
        ``(kind, window)`` pairs (window or lag in s).
    skip : float
        Transient dropped from the start of the record (s).

    Returns
    -------
    status : dict
        ``key, status ("ok" | "failed"), error, seconds``.

    Raises
    ------
    CampaignInterrupted
        When the run was interrupted by SIGTERM (the master's own signal guard ends
        the run); the case's temporary folder is removed and nothing is published.
    """
    cases_dir = Path(cases_dir)
    blocked = not_a_folder(cases_dir, case.key)
    if blocked:
        return {"key": case.key, "status": "failed", "error": blocked, "seconds": 0.0}
    tmp = temporary_folder(cases_dir, case.key)
    t0 = time.perf_counter()
    info = {"key": case.key, "label": case.label, "event": case.event,
            "configuration": case.configuration, "sweep": case.sweep, "scenario": case.scenario}
    try:
        try:
            table = _run(runner, case.scenario, tmp)
            write_table(_metrics_table(table, instruments, metrics, skip), tmp / METRICS_FILE)
            info.update(status="ok", error="",
                        files={n: file_record(tmp / n) for n in CASE_FILES})
        except Exception as exc:  # a failing case is recorded and does not stop the others
            result = getattr(exc, "result", None)
            if getattr(result, "metadata", {}).get("status") == "interrupted":
                raise CampaignInterrupted(signal.SIGTERM) from exc
            info.update(status="failed", error=one_sentence(exc),
                        traceback=traceback.format_exc(limit=8))
        info["seconds"] = round(time.perf_counter() - t0, 6)
        write_json(tmp / STATUS_FILE, info)
    except BaseException:     # interrupted: nothing of this case is published
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    publish(tmp, cases_dir / case.key)
    return {k: info[k] for k in ("key", "status", "error", "seconds")}


def _run(runner: Callable, scenario: dict, folder: Path) -> dict:
    """Run the runner into ``folder``; its table, written to ``folder/results.parquet``."""
    produced = runner(scenario, folder)
    results = folder / RESULTS_FILE
    if isinstance(produced, RunResult):
        if not results.is_file():
            raise FileNotFoundError(f"runner returned its table but wrote no {str(results)!r}")
        held = produced.metadata.get("unstable")
        if held:   # its jitter is that of the limits, not of the loop: not a budget value
            raise ValueError(held["message"])
        return produced.table
    res = Path(produced)
    if not res.is_file():
        raise FileNotFoundError(f"runner returned {str(res)!r}, which is not a file")
    if res.parent.resolve() != folder.resolve() or res.name != RESULTS_FILE:
        shutil.copyfile(res, results)
    return read_columns(results)


def one_sentence(exc: BaseException) -> str:
    msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    msg = f"{type(exc).__name__}: {msg}" if msg else type(exc).__name__
    return msg if len(msg) <= 300 else msg[:297] + "..."
