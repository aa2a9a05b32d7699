"""The linear engine as a campaign runner, and the co-simulated cross-check of its cases.

:class:`LinearRunner` is a runner like :class:`~orchestrator.campaign.MasterRunner`: it
writes a case's ``results.parquet`` (the scenario's recorded variables at its output
interval) and ``run.json``, so metrics, summary, budget, report and resume are those of a
co-simulated campaign.  The record comes from the discretised models the FMUs step
(:func:`~orchestrator.analysis.linearize`), closed once per configuration and driven by
the sources' own open-loop series (:class:`~orchestrator.analysis.fast.FastResponse`).
A case whose record reaches a rail or limit of an FMU fails with one sentence naming it.

:func:`verify_campaign` co-simulates the cases with the largest jitter and records, per
instrument and axis, the largest difference between the two engines.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import threading
import time
import warnings
from pathlib import Path

import numpy as np

from ..analysis import AnalysisError, linearize
from ..analysis.scenario import instance_block, loop_key
from ..analysis.fast import FastResponse
from ..cosim import UnconnectedInputWarning, find_fmu, prepare, read_fmu_info
from ..results import RunResult, package_versions, write_metadata, write_table
from .runner import MasterRunner
from .store import RESULTS_FILE, write_json

__all__ = ["LinearRunner", "verify_campaign"]


def _locked(method):
    """Run ``method`` holding the runner's lock (its caches are shared by threads)."""
    @functools.wraps(method)
    def inner(self, *args, **kwargs):
        with self._lock:
            return method(self, *args, **kwargs)
    return inner


class LinearRunner:
    """Run a case with the linear engine.

    Parameters
    ----------
    base_dir : path-like
        Folder against which FMU names are resolved (the base scenario's folder).
    fmu_dir : path-like, optional
        Extra folder searched first for FMU names.

    Notes
    -----
    Each configuration (the scenario with the sources' parameters left out) is
    linearised and compiled once; cases that differ only in their sources reuse it.
    Cases run in the calling process (the compiled loops are its memory); pickling the
    runner drops them.
    """

    engine = "linear"

    def __init__(self, base_dir=None, fmu_dir=None):
        self._master = MasterRunner(base_dir, fmu_dir, fmu_kind="python")
        self.fmu_dir = fmu_dir
        self._compiled = {}
        self._sources = {}
        self._source_blocks = {}
        self._series_cache = {}
        self._responses = {}
        self._gates = {}   # one build at a time per loop (compiled)
        # the caches of compiled loops and sources, shared by a campaign's threads
        self._lock = threading.RLock()

    def __getstate__(self):
        return {"_master": self._master, "fmu_dir": self.fmu_dir}

    def __setstate__(self, state):
        self.__init__(state["_master"].base_dir, state["fmu_dir"])

    def fingerprint(self, scenario: dict) -> str:
        """The FMU digest of the master runner, marked as the linear engine's."""
        return "engine=linear;" + self._master.fingerprint(scenario)

    def override_problem(self, scenario: dict, ref: str, values=()) -> str | None:
        """As :meth:`MasterRunner.override_problem`, on the Python FMUs it reads.

        Parameters
        ----------
        scenario, ref, values : dict, str, sequence
            A case's scenario data, ``"instance.variable"`` and the values it takes;
            returns one sentence, or None when they can be set.
        """
        return self._master.override_problem(scenario, ref, values)

    def unit_of(self, scenario: dict, ref: str) -> str:
        """As :meth:`MasterRunner.unit_of`: the unit the FMU declares for ``ref``.

        Parameters
        ----------
        scenario, ref : dict, str
            A case's scenario data and ``"instance.variable"``; returns ``""`` when
            it declares none.
        """
        return self._master.unit_of(scenario, ref)

    def output_problem(self, scenario: dict, ref: str, recorded: bool = True) -> str | None:
        """As :meth:`MasterRunner.output_problem` (an instrument's axis in the record).

        Parameters
        ----------
        scenario, ref : dict, str
            A case's scenario data and ``"instance.variable"``; returns one sentence,
            or None when the record gives it.
        recorded : bool
            It must be in ``[record] variables`` too.
        """
        return self._master.output_problem(scenario, ref, recorded)

    # ------------------------------------------------------------------ compiled loops
    def compiled(self, scenario: dict) -> FastResponse:
        """The compiled closed loop of a case's configuration (built on first use).

        Threads asking for different loops build them at once; a thread asking for a
        loop another is building waits for that build (one gate per loop)."""
        layout = json.dumps(sorted((n, f.get("fmu")) for n, f in scenario["fmus"].items()))
        with self._lock:
            sources = self._sources.get(layout)
            fr = None if sources is None else self._compiled.get(loop_key(scenario, sources))
        if fr is not None:
            return fr
        # linearised outside the runner's lock: the blocks two configurations share are
        # built once in the process (analysis.scenario.instance_block)
        sc = self._master._scenario(scenario)
        lin = linearize(sc, fmu_dir=self.fmu_dir)
        key = loop_key(scenario, lin.sources)
        with self._lock:
            self._sources[layout] = tuple(lin.sources)
            gate = self._gates.setdefault(key, threading.Lock())
        with gate:
            with self._lock:
                fr = self._compiled.get(key)
            if fr is None:
                # the model build: the loop's run matrices; the input side of each
                # source channel is built when a case first drives it (a budget's
                # events drive 17 of the EOS loop's 54 channels)
                fr = FastResponse(lin, tuple(sc.record)).prepare(channels=())
                with self._lock:
                    self._compiled[key] = fr
        return fr

    def response(self, scenario: dict, refs, opened=()) -> FastResponse:
        """The compiled loop of a case's configuration with ``opened`` instances taken
        out and ``refs`` recorded (kept: a second sweep on it reuses its factorisation).

        Parameters
        ----------
        scenario : dict
            A case's scenario data.
        refs : sequence of str
            Outputs to record.
        opened : sequence of str
            Instances whose outputs are held at zero (e.g. the ACS).
        """
        fr = self.compiled(scenario)   # not under the lock: another thread may be building
        if not opened and tuple(fr.refs) == tuple(refs):
            return fr
        key = (id(fr), tuple(opened), tuple(refs))
        with self._lock:
            got = self._responses.get(key)
            if got is None or got[0] is not fr:
                # held at zero: published every tick, so that they add no period
                lin = fr.lin.opened(opened, period=1) if opened else fr.lin
                got = self._responses[key] = (fr, FastResponse(lin, tuple(refs)))
        return got[1]

    @_locked
    def _source_block(self, fr: FastResponse, inst, cache: bool = True):
        """The block of a source instance with its parameters (kept unless ``cache``
        is false, e.g. for one sample's random phases)."""
        key = (inst.name, inst.fmu, json.dumps(dict(inst.parameters), sort_keys=True,
                                               default=str))
        b = self._source_blocks.get(key)
        if b is None:
            b = instance_block(fr.lin.plan, inst)
            if cache:
                self._source_blocks[key] = b
        return b

    def parameter_names(self, scenario: dict, name: str) -> tuple:
        """The parameters the FMU of instance ``name`` of a case declares.

        Parameters
        ----------
        scenario : dict
            A case's scenario data.
        name : str
            An instance of it.

        Returns
        -------
        tuple of str
        """
        sc = self._master._scenario(scenario)
        inst = next(i for i in sc.instances if i.name == name)
        info = read_fmu_info(find_fmu(inst.fmu, sc, self.fmu_dir))
        return tuple(k for k, v in info.variables.items() if v.causality == "parameter")

    @_locked
    def source_problem(self, scenario: dict, name: str, parameters: dict) -> str | None:
        """Why the source instance ``name`` of a case refuses ``parameters`` (its FMU's own
        check, e.g. a ``frequency_scale`` on a source that does not repeat); None if it
        takes them.  No loop is compiled: this serves co-simulated samples too.

        Parameters
        ----------
        scenario : dict
            A case's scenario data.
        name : str
            A source instance of it.
        parameters : dict
            Parameters replacing the instance's own.

        Returns
        -------
        str or None
            One sentence, or None.
        """
        sc = self._master._scenario(scenario).with_experiment(fmu_kind="python")
        inst = next(i for i in sc.instances if i.name == name)
        inst = dataclasses.replace(inst, parameters={**inst.parameters, **parameters})
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            plan = prepare(sc, self.fmu_dir)
        try:
            instance_block(plan, inst)
        except ValueError as exc:   # the source's own sentence (distfmu.sources.SourceError)
            return str(exc)
        return None

    def inputs(self, fr: FastResponse, scenario: dict, parameters=None) -> np.ndarray:
        """The source matrix ``W`` of a case on the compiled loop ``fr``.

        Parameters
        ----------
        fr : FastResponse
            :meth:`compiled` of the case.
        scenario : dict
            The case's scenario data (the sources' parameters are read from it).
        parameters : dict of str to dict, optional
            Per source, parameters replacing its own (one Monte Carlo sample's phase
            ``seed`` and ``frequency_scale``); those source blocks are not kept.

        Returns
        -------
        ndarray, shape (n_ticks + 1, m)

        Raises
        ------
        AnalysisError
            For a source without an open-loop series (an input-driven wheel).
        """
        parameters = parameters or {}
        sc = self._master._scenario(scenario)
        n_ticks = fr.lin.plan.timebase.n_ticks
        insts = {i.name: i for i in sc.instances}
        series = {}
        for name in fr.lin.sources:
            inst = insts[name]
            if name in parameters:
                inst = dataclasses.replace(inst, parameters={**inst.parameters,
                                                             **parameters[name]})
            series[name] = self._series(fr, inst, n_ticks, cache=name not in parameters)
        return fr.input_matrix(series, n_ticks)

    @_locked
    def _series(self, fr: FastResponse, inst, n_ticks: int, cache: bool = True):
        """A source's open-loop series at its sample times (kept, read-only, unless
        ``cache`` is false: the configurations of a campaign share their events)."""
        b = self._source_block(fr, inst, cache)
        if b.series is None:
            raise AnalysisError(f"source {inst.name!r} has no open-loop series (an input-"
                                "driven wheel); the linear engine cannot drive it: run "
                                "this case with the co-simulation (--engine cosim)")
        times = fr.times(n_ticks, b.period)
        key = (id(b), times.size, float(times[0]) if times.size else 0.0,
               float(times[-1]) if times.size else 0.0)
        hit = self._series_cache.get(key) if cache else None
        if hit is not None:
            return hit[1]
        values = np.asarray(b.series(times))
        if cache:
            values.flags.writeable = False
            if len(self._series_cache) >= 256:   # a bound, whatever the campaign
                self._series_cache.clear()
            self._series_cache[key] = (b, values)   # b kept, so its id stays unique
        return values

    def record(self, scenario: dict):
        """A case's record and the output stride of its table.

        A checked output that is not recorded is bounded where that keeps it inside its
        range; its ``limits`` entry is then that bound (``Record.bounded`` names them).

        Raises
        ------
        AnalysisError
            Where the scenario holds what the linear model cannot represent, or
            :class:`~orchestrator.analysis.fast.NonlinearError` where the record reaches
            a rail or limit.
        """
        fr = self.compiled(scenario)
        # a checked output that is not recorded is computed only where a rigorous bound
        # does not keep it inside its range: whether a rail is reached stays exact
        rec = fr.run_many([self.inputs(fr, scenario)], check=True, bound_limits=True)[0]
        return rec, fr.lin.plan.timebase.output_ticks

    def __call__(self, scenario: dict, out_dir) -> RunResult:
        """Run a case's scenario into ``out_dir`` (``results.parquet``, ``run.json``).

        Returns
        -------
        RunResult
        """
        wall = time.perf_counter()
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        rec, every = self.record(scenario)
        table = {"time": rec.times[::every]}
        for j, ref in enumerate(rec.refs):
            table[ref] = rec.values[::every, j].copy()
        write_table(table, out / RESULTS_FILE)
        # the fraction of each range used, and for what a bound cleared, that bound
        used = {k: v for k, v in rec.limits.items() if k not in rec.bounded}
        bound = {k: v for k, v in rec.limits.items() if k in rec.bounded}
        meta = {"status": "ok", "engine": "linear", "rows": len(table["time"]),
                "limits_used": used, "limits_bound": bound,
                "wall_s": time.perf_counter() - wall, "versions": package_versions()}
        write_metadata(meta, out / "run.json")
        return RunResult(table, meta, out)


# ---------------------------------------------------------------------------------------
# Cross-check


def verify_campaign(campaign, out_dir, n: int = 2, *, fmu_dir=None, fmu_kind=None) -> dict:
    """Co-simulate the ``n`` linear cases with the largest jitter and compare.

    The cases are ranked by their largest metric value over instruments and axes
    (relative to its requirement where one is set).  Each is run by the co-simulation
    master into ``out_dir/verify/KEY`` with every piezo FMU's saturation flags added to
    the record; the report holds, per case, instrument and axis, the largest difference
    of the recorded line of sight and of every metric, relative to the co-simulated
    value, and whether a rail, slew or stroke flag was set during the run.

    Parameters
    ----------
    campaign : Campaign
        A campaign run with the linear engine (its case folders exist).
    out_dir : path-like
        The campaign folder.
    n : int
        Number of cases to co-simulate.
    fmu_dir, fmu_kind
        As :class:`~orchestrator.campaign.MasterRunner`.

    Returns
    -------
    dict
        Written to ``out_dir/verify.json``.
    """
    import pyarrow.parquet as pq

    from .runner import case_metrics
    from .spec import ANGLE_UNITS
    from .store import METRICS_FILE, case_status

    out = Path(out_dir)
    cases_dir = out / "cases"
    ranked = []
    for case in campaign.cases:
        st = case_status(cases_dir, case.key)
        if not st or st.get("status") != "ok":
            continue
        worst = 0.0
        for r in pq.read_table(cases_dir / case.key / METRICS_FILE).to_pylist():
            req = campaign.requirement(r["instrument"], r["axis"], r["metric"], r["window"])
            v = r["value"] * ANGLE_UNITS[campaign.unit]
            worst = max(worst, v / req if req and not math.isnan(req) else v)
        ranked.append((worst, case))
    ranked.sort(key=lambda p: -p[0])
    master = MasterRunner(campaign.scenario_dir, fmu_dir=fmu_dir, fmu_kind=fmu_kind)
    report = {"n": 0, "cases": [], "largest_difference": {}, "nonlinear": []}
    for _, case in ranked[:max(0, int(n))]:
        scen = json.loads(json.dumps(case.scenario))
        record = list(scen.get("record", {}).get("variables", []))
        flags = [f"{name}.{flag}" for name, f in scen["fmus"].items()
                 for flag in ("sat_voltage", "sat_slew", "sat_stroke")
                 if "piezo" in str(f.get("fmu", ""))]
        scen.setdefault("record", {})["variables"] = record + [f for f in flags
                                                               if f not in record]
        folder = out / "verify" / case.key
        try:
            with warnings.catch_warnings():   # the campaign's cases warned already
                warnings.simplefilter("ignore", UnconnectedInputWarning)
                co = master(scen, folder).table
        except Exception as exc:   # the cross-check reports, never hides, a failure
            report["cases"].append({"case": case.label, "key": case.key,
                                    "error": f"{type(exc).__name__}: {exc}"})
            continue
        lin = pq.read_table(cases_dir / case.key / RESULTS_FILE).to_pydict()
        set_flags = [f for f in flags if f in co and np.any(np.asarray(co[f]) != 0)]
        rows_co = case_metrics(co["time"], co, campaign.instruments, campaign.metrics,
                               campaign.skip)
        rows_li = case_metrics(lin["time"], lin, campaign.instruments, campaign.metrics,
                               campaign.skip)
        entry = {"case": case.label, "key": case.key, "nonlinear_flags": set_flags,
                 "axes": {}}
        for a, b in zip(rows_co, rows_li):
            ia = f"{a['instrument']}/{a['axis']}"
            var = campaign.instruments[a["instrument"]][a["axis"]]
            x, y = np.asarray(co[var]), np.asarray(lin[var])
            sig = float(np.max(np.abs(x - y)) / max(np.max(np.abs(x)), 1e-300))
            met = abs(a["value"] - b["value"]) / max(abs(a["value"]), 1e-300)
            d = entry["axes"].setdefault(ia, {"signal": sig, "metric": 0.0})
            d["metric"] = max(d["metric"], float(met))
            big = report["largest_difference"].setdefault(ia, {"signal": 0.0, "metric": 0.0})
            big["signal"] = max(big["signal"], sig)
            big["metric"] = max(big["metric"], d["metric"])
        if set_flags:
            report["nonlinear"].append({"case": case.label, "flags": set_flags})
        report["cases"].append(entry)
        report["n"] += 1
    write_json(out / "verify.json", report)
    return report
