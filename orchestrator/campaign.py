"""Campaigns: many scenario runs (events × configurations × sweeps), their jitter and budget.

A campaign is a base scenario plus a matrix of cases.  Every case applies parameter
overrides to the base scenario — one disturbance event (each event runs alone), one
configuration (e.g. isolation off / on) and one point of the parameter sweeps — and is run
by a *runner*, any callable ``runner(scenario_dict, out_dir) -> path of results.parquet``.
The default runner is the co-simulation master (:class:`MasterRunner`); tests and scripts may
pass any picklable callable.  Each finished case's recorded line-of-sight (LOS) angles are
turned into jitter metrics (:mod:`orchestrator.metrics`), and the campaign's summary holds
one row per case, instrument, axis, metric and window plus the RSS over events of every
configuration and sweep point, against the requirements.

Campaign file (TOML)::

    [campaign]
    name = "truss10_quick"
    scenario = "../scenarios/truss10.toml"   # base scenario, relative to this file
    unit = "arcsec"                          # unit of the summary, requirements and report
    skip = 0.5                               # s of transient dropped from every record
    stop = 5.0                               # optional experiment overrides of the base
    output_interval = 1e-3

    [[events]]                               # each case turns on exactly one event
    name = "VNIR pointing"
    overrides = { "dist.amplitude" = 1.0, "dist.frequency" = 8.4 }

    [[configurations]]                       # every event runs in every configuration
    name = "isolation off"
    overrides = { "ctrl.enable" = false }

    [[sweeps]]                               # optional, cartesian product of all sweeps
    parameter = "structure.zeta"
    values = [0.002, 0.004]

    [[instruments]]                          # recorded LOS angles (rad) per axis
    name = "SWIR"
    axes = { pitch = "structure.los_swir_pitch", yaw = "structure.los_swir_yaw" }

    [[metrics]]                              # kind and windows (s); stability: lags (s)
    kind = "peak_to_peak"                    # peak_to_peak | rms_jitter | stability | rms
    windows = [1.8]

    [[requirements]]                         # in `unit`; axis and window optional
    instrument = "SWIR"
    metric = "peak_to_peak"
    window = 1.8
    value = 2.0

Output folder::

    DIR/campaign.json          the expanded campaign (cases, keys)
    DIR/cases/KEY/case.json    definition, status ("ok" or "failed"), error, timings
    DIR/cases/KEY/results.parquet, metrics.parquet   (successful cases)
    DIR/cases.parquet, cases.csv       one row per case with its status and error
    DIR/summary.parquet, summary.csv   the jitter table (see :func:`summarize`)

Resuming
--------
A case is keyed by the SHA-256 of its definition (scenario after overrides, instruments,
metrics, skip) and of the runner's fingerprint of the FMUs it uses.  A case runs in a
temporary folder which is renamed to ``cases/KEY`` (``os.replace``) only when complete, so
a killed campaign loses only the cases in flight; running the campaign again skips every
case whose folder says "ok" and retries failed ones.

Parallelism
-----------
``workers=0`` runs the cases one after another in this process; ``workers >= 1`` uses a
process pool (forkserver on Linux, spawn elsewhere) with at most ``workers`` cases in
flight; ``scheduler="tcp://..."`` (or a ``distributed.Client``) submits them to an existing
Dask cluster whose workers must see ``DIR`` (shared file system).  Every mode computes the
same numbers: each case is a pure function of its definition.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import multiprocessing
import os
import re
import shutil
import time
import tomllib
import traceback
import uuid
from collections.abc import Callable, Mapping
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from fmukit.units import ARCSEC_PER_RAD, DEG_PER_RAD

from . import metrics as M
from .files import atomic_write, sha256_file, write_json_atomic
from .progress import ProgressBar

__all__ = [
    "ANGLE_UNITS",
    "METRIC_KINDS",
    "Campaign",
    "CampaignError",
    "CampaignResult",
    "Case",
    "MasterRunner",
    "campaign_from_dict",
    "case_metrics",
    "execute_case",
    "keyed",
    "load_campaign",
    "run_campaign",
    "summarize",
    "write_summary",
]

#: Factor from rad to each supported reporting unit.
ANGLE_UNITS = {
    "rad": 1.0,
    "mrad": 1e3,
    "urad": 1e6,
    "deg": DEG_PER_RAD,
    "arcsec": ARCSEC_PER_RAD,
}
#: Metric kinds and what their ``windows`` mean.
METRIC_KINDS = {
    "peak_to_peak": "windowed peak-to-peak jitter over T (s)",
    "rms_jitter": "RMS deviation from the window mean over T (s)",
    "stability": "RMS change across a lag Ts (s)",
    "rms": "RMS about the record mean (no window)",
}
RSS_EVENT = "RSS"
# Valid keys of every table of a campaign file.
_KEYS = ("campaign", "events", "configurations", "sweeps", "instruments", "metrics",
         "requirements")
_CAMPAIGN_KEYS = ("name", "scenario", "unit", "skip", "stop", "output_interval", "algorithm")
_ITEM_KEYS = {
    "events": ("name", "overrides"),
    "configurations": ("name", "overrides"),
    "sweeps": ("parameter", "values"),
    "instruments": ("name", "axes", "requirement"),
    "metrics": ("kind", "windows", "window"),
    "requirements": ("instrument", "value", "axis", "metric", "window"),
}
_STATUS_FILE = "case.json"


class CampaignError(ValueError):
    """A campaign definition that is malformed or inconsistent."""


# ----------------------------------------------------------------------------- definition


@dataclass(frozen=True)
class Case:
    """One run of a campaign.

    Attributes
    ----------
    key : str
        Hex SHA-256 of the case definition and the runner's fingerprint.
    label : str
        Readable name, ``event | configuration | sweep``.
    event, configuration, sweep : str
        Coordinates in the campaign matrix (``sweep`` is ``"p=v, ..."`` or ``""``).
    scenario : dict
        Scenario data (the TOML layout) after the case's overrides.
    """

    key: str
    label: str
    event: str
    configuration: str
    sweep: str
    scenario: dict


@dataclass(frozen=True)
class Campaign:
    """A campaign expanded into cases.

    Attributes
    ----------
    name : str
    cases : tuple of Case
    instruments : dict of str to dict of str to str
        ``{instrument: {axis: recorded variable}}``; recorded LOS angles in rad.
    metrics : tuple of (str, float or None)
        ``(kind, window)`` pairs; window in s (the lag for ``stability``).
    requirements : tuple of dict
        Items with ``instrument``, ``value`` and optional ``axis``, ``metric``, ``window``.
    unit : str
        Reporting unit, a key of :data:`ANGLE_UNITS`.
    skip : float
        Transient dropped from the start of every record (s).
    base_dir : Path
        Folder of the campaign file (relative paths are resolved against it).
    scenario_dir : Path
        Folder of the base scenario (FMU names are resolved against it).
    """

    name: str
    cases: tuple
    instruments: dict
    metrics: tuple
    requirements: tuple = ()
    unit: str = "arcsec"
    skip: float = 0.0
    base_dir: Path = field(default_factory=Path.cwd)
    scenario_dir: Path = field(default_factory=Path.cwd)

    def requirement(self, instrument: str, axis: str, metric: str, window) -> float:
        """Requirement (in ``unit``) for one summary row, NaN if none applies.

        The most specific matching item wins (axis, metric and window each count).
        """
        best, score = math.nan, -1
        for r in self.requirements:
            if r["instrument"] != instrument:
                continue
            s = 0
            for key, value in (("axis", axis), ("metric", metric), ("window", window)):
                if key in r:
                    if key == "window":
                        if value is None or not math.isclose(float(r[key]), float(value)):
                            break
                    elif r[key] != value:
                        break
                    s += 1
            else:
                if s > score:
                    best, score = float(r["value"]), s
        return best


def _canonical(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


def _check_requirement(r: dict, number: int, axes: dict, metrics: list) -> None:
    """A requirement's axis, metric and window must match something, else it never applies."""
    from .scenario import closest

    what = f"requirement {number} ({r['instrument']})"
    if "axis" in r and r["axis"] not in axes:
        raise CampaignError(f"{what} has axis {r['axis']!r}{closest(r['axis'], axes)}; "
                            f"expected one of {', '.join(axes)}")
    if "metric" in r and r["metric"] not in METRIC_KINDS:
        raise CampaignError(f"{what} has metric {r['metric']!r}{closest(r['metric'], METRIC_KINDS)}"
                            f"; expected one of {', '.join(METRIC_KINDS)}")
    if "window" in r:
        w = r["window"]
        windows = sorted({win for kind, win in metrics if win is not None
                          and r.get("metric", kind) == kind})
        if not (isinstance(w, (int, float)) and not isinstance(w, bool)
                and any(math.isclose(float(w), win) for win in windows)):
            raise CampaignError(f"{what} has window {w!r} s, which no [[metrics]] entry "
                                f"computes; expected one of {windows}")
    value = r["value"]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 \
            or not math.isfinite(value):
        raise CampaignError(f"{what} has value {value!r}; expected a positive number")


def _overrides(item, what: str) -> dict:
    ov = item.get("overrides", {})
    if not isinstance(ov, dict):
        raise CampaignError(f"{what} overrides must be a table of 'instance.variable' = value")
    for k in ov:
        if "." not in k:
            raise CampaignError(f"{what} override {k!r} must have the form 'instance.variable'")
    return dict(ov)


def _check_keys(table, allowed, what: str) -> None:
    from .scenario import check_keys

    check_keys(table, allowed, what, CampaignError)


def _table_list(items, what: str, allowed) -> list:
    """Check an array of tables ``[[what]]`` and the keys of each of its tables."""
    if not isinstance(items, list):
        raise CampaignError(f"{what} must be an array of tables ([[{what}]])")
    for i, it in enumerate(items):
        if not isinstance(it, dict):
            raise CampaignError(f"[[{what}]] entry {i + 1} is a {type(it).__name__}; expected "
                                "a table")
        label = f" ({it['name']!r})" if isinstance(it.get("name"), str) else ""
        _check_keys(it, allowed, f"[[{what}]] entry {i + 1}{label}")
    return items


def _named(items, what: str) -> list:
    _table_list(items, what, _ITEM_KEYS[what])
    names = []
    for i, it in enumerate(items):
        if "name" not in it:
            raise CampaignError(f"{what} entry {i + 1} has no 'name'")
        names.append(str(it["name"]))
    if len(set(names)) != len(names):
        raise CampaignError(f"{what} names are not unique: {names}")
    return names


def _apply(scenario: dict, overrides: dict) -> dict:
    out = json.loads(json.dumps(scenario))  # deep copy, plain data
    fmus = out.get("fmus", {})
    for key, value in overrides.items():
        inst, var = key.split(".", 1)
        if inst not in fmus:
            raise CampaignError(
                f"override {key!r} names instance {inst!r}, which the base scenario does "
                f"not have (instances: {sorted(fmus)})"
            )
        fmus[inst].setdefault("parameters", {})[var] = value
    return out


def campaign_from_dict(data: Mapping, base_dir=None) -> Campaign:
    """Expand campaign data (the TOML layout) into a :class:`Campaign`.

    Parameters
    ----------
    data : mapping
        Tables ``campaign``, ``events``, ``configurations``, ``sweeps``, ``instruments``,
        ``metrics``, ``requirements``.  ``campaign.scenario`` is a path to the base scenario
        TOML or an inline table (the scenario layout).
    base_dir : path-like, optional
        Folder for relative paths (default: current folder).

    Returns
    -------
    Campaign
        Cases keyed by the SHA-256 of their definition; :func:`run_campaign` mixes in the
        runner's fingerprint (:func:`keyed`).
    """
    base_dir = Path(base_dir or Path.cwd()).resolve()
    head = data.get("campaign")
    if not isinstance(head, dict):
        raise CampaignError("campaign file has no [campaign] table")
    _check_keys(data, _KEYS, "campaign file")
    _check_keys(head, _CAMPAIGN_KEYS, "[campaign]")
    name = str(head.get("name", "campaign"))
    scen = head.get("scenario")
    if isinstance(scen, str):
        path = (base_dir / scen).resolve()
        if not path.is_file():
            raise CampaignError(f"base scenario {str(path)!r} of campaign {name!r} does not exist")
        scenario = tomllib.loads(path.read_text(encoding="utf-8"))
        scen_dir = path.parent
    elif isinstance(scen, dict):
        scenario, scen_dir = json.loads(json.dumps(scen)), base_dir
    else:
        raise CampaignError("[campaign] scenario must be a path to a TOML file or a table")
    if not isinstance(scenario.get("fmus"), dict) or not scenario["fmus"]:
        raise CampaignError(f"base scenario of campaign {name!r} has no [fmus.NAME] tables")
    # FMU names stay as written; paths to .fmu files are made absolute so cases run anywhere.
    for spec in scenario["fmus"].values():
        fmu = str(spec.get("fmu", ""))
        if fmu.endswith(".fmu") and not Path(fmu).is_absolute():
            spec["fmu"] = str((scen_dir / fmu).resolve())
    exp = scenario.setdefault("experiment", {})
    for k in ("stop", "output_interval", "algorithm"):
        if k in head:
            exp[k] = head[k]
    unit = str(head.get("unit", "arcsec"))
    if unit not in ANGLE_UNITS:
        raise CampaignError(f"[campaign] unit is {unit!r}; expected one of {sorted(ANGLE_UNITS)}")
    skip = float(head.get("skip", 0.0))
    if not skip >= 0:
        raise CampaignError(f"[campaign] skip is {skip!r} s; expected >= 0")

    events = data.get("events", [{"name": "baseline"}])
    configurations = data.get("configurations", [{"name": "baseline"}])
    ev_names = _named(events, "events")
    cf_names = _named(configurations, "configurations")
    if RSS_EVENT in ev_names:
        raise CampaignError(f"event name {RSS_EVENT!r} is reserved for the RSS total")
    sweeps = _table_list(data.get("sweeps", []), "sweeps", _ITEM_KEYS["sweeps"])
    axes_sweep = []
    for i, s in enumerate(sweeps):
        if not isinstance(s, dict) or "parameter" not in s or not s.get("values"):
            raise CampaignError(f"sweep {i + 1} needs 'parameter' and a non-empty 'values'")
        axes_sweep.append([(str(s["parameter"]), v) for v in s["values"]])

    instruments = data.get("instruments")
    if not isinstance(instruments, list) or not instruments:
        raise CampaignError("campaign has no [[instruments]] (name and axes of recorded LOS)")
    _table_list(instruments, "instruments", _ITEM_KEYS["instruments"])
    inst_map = {}
    shorthand = []
    for i, it in enumerate(instruments):
        if not isinstance(it, dict) or "name" not in it or not isinstance(it.get("axes"), dict):
            raise CampaignError(f"instrument {i + 1} needs 'name' and 'axes' = {{axis = var}}")
        if it["name"] in inst_map:
            raise CampaignError(f"instrument {it['name']!r} is defined twice")
        inst_map[str(it["name"])] = {str(a): str(v) for a, v in it["axes"].items()}
        if "requirement" in it:  # shorthand: one value for every axis, metric and window
            shorthand.append({"instrument": str(it["name"]), "value": it["requirement"]})

    metric_items = data.get("metrics", [{"kind": "peak_to_peak", "windows": [1.0]}])
    _table_list(metric_items, "metrics", _ITEM_KEYS["metrics"])
    metrics = []
    for i, m in enumerate(metric_items):
        kind = m.get("kind") if isinstance(m, dict) else None
        if kind not in METRIC_KINDS:
            raise CampaignError(
                f"metric {i + 1} kind is {kind!r}; expected one of {sorted(METRIC_KINDS)}"
            )
        if kind == "rms":
            metrics.append((kind, None))
            continue
        windows = m.get("windows", [m["window"]] if "window" in m else [])
        if not windows:
            raise CampaignError(f"metric {i + 1} ({kind}) needs 'windows' (s)")
        for w in windows:
            if not (isinstance(w, (int, float)) and w > 0):
                raise CampaignError(f"metric {i + 1} ({kind}) window {w!r} is not a positive time")
            metrics.append((kind, float(w)))

    reqs = []
    explicit = _table_list(data.get("requirements", []), "requirements",
                           _ITEM_KEYS["requirements"])
    for i, r in enumerate(list(explicit) + shorthand):
        if "instrument" not in r or "value" not in r:
            raise CampaignError(f"requirement {i + 1} needs 'instrument' and 'value'")
        if r["instrument"] not in inst_map:
            raise CampaignError(
                f"requirement {i + 1} names unknown instrument {r['instrument']!r} "
                f"(instruments: {sorted(inst_map)})"
            )
        _check_requirement(r, i + 1, inst_map[r["instrument"]], metrics)
        reqs.append(dict(r))

    cases = []
    for ev, cf in itertools.product(events, configurations):
        ov_e = _overrides(ev, f"event {ev['name']!r}")
        ov_c = _overrides(cf, f"configuration {cf['name']!r}")
        for point in itertools.product(*axes_sweep) if axes_sweep else [()]:
            ov = {**ov_c, **ov_e, **dict(point)}
            scenario_case = _apply(scenario, ov)
            sweep = ", ".join(f"{p}={v}" for p, v in point)
            definition = {
                "scenario": scenario_case,
                "instruments": inst_map,
                "metrics": metrics,
                "skip": skip,
            }
            key = hashlib.sha256(_canonical(definition).encode()).hexdigest()
            label = " | ".join(x for x in (str(ev["name"]), str(cf["name"]), sweep) if x)
            cases.append(Case(key, label, str(ev["name"]), str(cf["name"]), sweep, scenario_case))
    keys = [c.key for c in cases]
    if len(set(keys)) != len(keys):
        dup = [c.label for c in cases if keys.count(c.key) > 1]
        raise CampaignError(f"cases {dup} have identical definitions; make their overrides differ")
    return Campaign(name, tuple(cases), inst_map, tuple(metrics), tuple(reqs), unit, skip,
                    base_dir, scen_dir)


def load_campaign(path) -> Campaign:
    """Read a campaign TOML file (see the module docstring for the layout).

    Parameters
    ----------
    path : path-like
        Campaign file.

    Returns
    -------
    Campaign
    """
    path = Path(path)
    if not path.is_file():
        raise CampaignError(f"campaign file {str(path)!r} does not exist")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise CampaignError(f"campaign file {str(path)!r} is not valid TOML: {exc}") from None
    return campaign_from_dict(data, path.parent)


# ----------------------------------------------------------------------------- runner


class MasterRunner:
    """Run a case with the co-simulation master (imported when first called).

    Parameters
    ----------
    base_dir : path-like
        Folder against which the FMU names of a case's scenario are resolved (the base
        scenario's folder), as :func:`orchestrator.cosim.find_fmu` does for a scenario file.
    fmu_dir : path-like, optional
        Extra folder searched first for FMU names.

    Notes
    -----
    Picklable, so it runs in pool and Dask workers.  :meth:`fingerprint` returns the
    SHA-256 of every FMU file a scenario uses, so rebuilt FMUs change the case keys.
    """

    def __init__(self, base_dir=None, fmu_dir=None):
        self.base_dir = Path(base_dir or Path.cwd()).resolve()
        self.fmu_dir = None if fmu_dir is None else Path(fmu_dir).resolve()

    def _scenario(self, scenario: dict):
        from .scenario import scenario_from_dict

        return scenario_from_dict(scenario, self.base_dir, source="<campaign case>")

    def fingerprint(self, scenario: dict) -> str:
        """SHA-256 over the FMU files the scenario uses ("missing" for absent ones)."""
        from .cosim import find_fmu

        sc = self._scenario(scenario)
        h = hashlib.sha256()
        for inst in sorted(sc.instances, key=lambda i: i.name):
            h.update(f"{inst.name}:{inst.fmu}:".encode())
            try:
                path = find_fmu(inst.fmu, sc, self.fmu_dir)
            except ValueError:
                h.update(b"missing")
                continue
            with open(path, "rb") as f:
                for chunk in iter(lambda: f.read(1 << 20), b""):
                    h.update(chunk)
        return h.hexdigest()

    def __call__(self, scenario: dict, out_dir) -> Path:
        from .run import run_scenario

        run_scenario(self._scenario(scenario), out_dir, quiet=True, fmu_dir=self.fmu_dir)
        return Path(out_dir) / "results.parquet"


def keyed(campaign: Campaign, runner) -> Campaign:
    """Mix the runner's fingerprint of each case (e.g. FMU checksums) into its key.

    Parameters
    ----------
    campaign : Campaign
        Cases keyed by their definition only.
    runner : callable
        Case runner; if it has ``fingerprint(scenario_dict) -> str`` that string enters
        every key, so a rebuilt FMU makes its cases run again.

    Returns
    -------
    Campaign
        Same campaign, final keys.
    """
    fp = getattr(runner, "fingerprint", None)
    if fp is None:
        return campaign
    cases = []
    for c in campaign.cases:
        extra = fp(c.scenario)
        key = hashlib.sha256(f"{c.key}\n{extra}".encode()).hexdigest()
        cases.append(dataclasses.replace(c, key=key))
    return dataclasses.replace(campaign, cases=tuple(cases))


# ----------------------------------------------------------------------------- one case


def _read_results(path) -> tuple[np.ndarray, dict]:
    table = pq.read_table(path)
    names = table.column_names
    tcol = next((c for c in ("time", "t", "time_s") if c in names), None)
    if tcol is None:
        raise ValueError(f"results file {Path(path).name} has no 'time' column (has {names[:5]})")
    t = table.column(tcol).to_numpy().astype(float)
    return t, {c: table.column(c) for c in names if c != tcol}


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
        raise ValueError("results time column is not uniformly spaced; expected one output interval")
    keep = t >= t[0] + skip - 0.5 * dt
    rows = []
    for inst, axes in instruments.items():
        for axis, var in axes.items():
            if var not in columns:
                raise KeyError(
                    f"recorded variable {var!r} for {inst}/{axis} is not in the results; "
                    "add it to [record] variables of the scenario"
                )
            x = np.asarray(columns[var], dtype=float)[keep]
            for kind, w in metrics:
                if kind == "peak_to_peak":
                    v = M.peak_to_peak(x, dt, w, short="whole")
                elif kind == "rms_jitter":
                    v = M.jitter_rms(x, dt, w)
                elif kind == "stability":
                    v = M.stability_rms(x, dt, w)
                else:
                    v = float(np.std(x))
                rows.append(dict(instrument=inst, axis=axis, metric=kind, window=w,
                                 value=float(v)))
    return rows


def _one_sentence(exc: BaseException) -> str:
    msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    msg = f"{type(exc).__name__}: {msg}" if msg else type(exc).__name__
    return msg if len(msg) <= 300 else msg[:297] + "..."


def _write_json_atomic(path: Path, data) -> None:
    write_json_atomic(path, data, indent=1, sort_keys=True, default=str)


def _write_table_atomic(table: pa.Table, path: Path, csv: bool = False) -> None:
    atomic_write(path, (lambda tmp: pacsv.write_csv(table, tmp)) if csv
                 else (lambda tmp: pq.write_table(table, tmp)))


def execute_case(case: Case, runner: Callable, cases_dir, instruments, metrics, skip) -> dict:
    """Run one case and publish its folder atomically; never raises for case errors.

    The runner works in ``cases_dir/.tmp-KEY-RANDOM``; the folder is renamed to
    ``cases_dir/KEY`` when results, metrics and ``case.json`` are written.

    Returns
    -------
    status : dict
        ``key, status ("ok" | "failed"), error, seconds``.
    """
    cases_dir = Path(cases_dir)
    tmp = cases_dir / f".tmp-{case.key}-{uuid.uuid4().hex[:8]}"
    tmp.mkdir(parents=True)
    t0 = time.perf_counter()
    info = {"key": case.key, "label": case.label, "event": case.event,
            "configuration": case.configuration, "sweep": case.sweep, "scenario": case.scenario}
    try:
        res = Path(runner(case.scenario, tmp))
        if not res.is_file():
            raise FileNotFoundError(f"runner returned {str(res)!r}, which is not a file")
        if res.parent.resolve() != tmp.resolve() or res.name != "results.parquet":
            shutil.copyfile(res, tmp / "results.parquet")
        t, cols = _read_results(tmp / "results.parquet")
        rows = case_metrics(t, cols, instruments, metrics, skip)
        table = pa.Table.from_pylist(rows, schema=_METRIC_SCHEMA)
        _write_table_atomic(table, tmp / "metrics.parquet")
        info.update(status="ok", error="", files={n: _file_record(tmp / n) for n in _CASE_FILES})
    except Exception as exc:  # a failing case is recorded and does not stop the others
        info.update(status="failed", error=_one_sentence(exc),
                    traceback=traceback.format_exc(limit=8))
    info["seconds"] = round(time.perf_counter() - t0, 6)
    _write_json_atomic(tmp / _STATUS_FILE, info)
    final = cases_dir / case.key
    if final.exists():  # an earlier failed attempt
        shutil.rmtree(final, ignore_errors=True)
    os.replace(tmp, final)
    return {k: info[k] for k in ("key", "status", "error", "seconds")}


_METRIC_SCHEMA = pa.schema([
    ("instrument", pa.string()), ("axis", pa.string()), ("metric", pa.string()),
    ("window", pa.float64()), ("value", pa.float64()),
])


_CASE_FILES = ("results.parquet", "metrics.parquet")


def _file_record(path: Path) -> dict:
    return {"size": path.stat().st_size, "sha256": sha256_file(path)}


def _case_verified(cases_dir: Path, key: str) -> bool:
    """A finished case whose files are the ones its ``case.json`` recorded.

    Status ``ok`` and, for every file of :data:`_CASE_FILES`, the recorded size and
    SHA-256; a truncated, replaced or missing file (or a ``case.json`` without the
    record) makes the case run again.
    """
    st = _case_status(cases_dir, key)
    if st is None or st.get("status") != "ok" or not isinstance(st.get("files"), dict):
        return False
    folder = cases_dir / key
    for name in _CASE_FILES:
        rec, path = st["files"].get(name), folder / name
        if not isinstance(rec, dict) or not path.is_file():
            return False
        if path.stat().st_size != rec.get("size") or _file_record(path) != rec:
            return False
    return True


def _case_status(cases_dir: Path, key: str) -> dict | None:
    p = cases_dir / key / _STATUS_FILE
    if not p.is_file():
        return None
    try:
        return json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


# ----------------------------------------------------------------------------- progress


# ----------------------------------------------------------------------------- engine


@dataclass(frozen=True)
class CampaignResult:
    """What a campaign run did.

    Attributes
    ----------
    out_dir : Path
    n_cases, n_run, n_skipped, n_failed : int
        All cases; run now; skipped because already finished; failed (now).
    summary : Path
        ``summary.parquet``.
    failures : dict of str to str
        Case label to one-sentence error.
    """

    out_dir: Path
    n_cases: int
    n_run: int
    n_skipped: int
    n_failed: int
    summary: Path
    failures: dict

    def __iter__(self):
        return iter((self.n_failed, self.summary))


def _pool_context():
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


def _run_local(todo, args, workers, on_done):
    """Process pool with at most ``workers`` cases in flight; survives dead workers."""
    queue = list(todo)
    while queue:
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=_pool_context(),
                                   initializer=_die_with_parent, initargs=(os.getpid(),))
        inflight = {}
        broken = False
        try:
            while queue or inflight:
                while queue and len(inflight) < workers and not broken:
                    case = queue.pop(0)
                    inflight[pool.submit(execute_case, case, *args)] = case
                if not inflight:
                    break
                done, _ = wait(inflight, return_when=FIRST_COMPLETED)
                for fut in done:
                    case = inflight.pop(fut)
                    try:
                        on_done(case, fut.result())
                    except BrokenProcessPool:
                        broken = True
                        on_done(case, _lost(case, "a worker process died while this case ran"))
                if broken:
                    for fut, case in inflight.items():
                        on_done(case, _lost(case, "a worker process died while this case ran"))
                    inflight.clear()
                    break
        finally:
            pool.shutdown(wait=not broken, cancel_futures=True)


def _lost(case: Case, why: str) -> dict:
    return {"key": case.key, "status": "failed", "error": why, "seconds": float("nan"),
            "unpublished": True}


def _run_dask(todo, args, scheduler, on_done):
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise CampaignError(
            "a Dask scheduler was given but the 'distributed' package is not installed "
            "(install the 'cluster' extra)"
        ) from None
    own = not hasattr(scheduler, "submit")
    client = Client(scheduler) if own else scheduler
    try:
        futs = {client.submit(execute_case, case, *args, key=f"case-{case.key}", pure=False): case
                for case in todo}
        for fut in as_completed(futs):
            case = futs[fut]
            try:
                on_done(case, fut.result())
            except Exception as exc:  # the worker died or the task was lost
                on_done(case, _lost(case, _one_sentence(exc)))
    finally:
        if own:
            client.close()


def run_campaign(
    campaign: Campaign,
    out_dir,
    runner: Callable | None = None,
    *,
    workers: int | None = None,
    scheduler=None,
    progress: bool | None = None,
) -> CampaignResult:
    """Run every unfinished case of a campaign and write the summary.

    Parameters
    ----------
    campaign : Campaign
        From :func:`load_campaign` or :func:`campaign_from_dict`.
    out_dir : path-like
        Output folder (created; reused to resume).
    runner : callable, optional
        ``runner(scenario_dict, out_dir) -> path of results.parquet``; picklable for
        ``workers >= 1`` and Dask.  Default: :class:`MasterRunner`.  If it has a
        ``fingerprint(scenario_dict) -> str`` method, that enters the case keys.
    workers : int, optional
        0 runs the cases in this process; N >= 1 uses N worker processes.  Default: the
        number of CPUs.  Ignored when ``scheduler`` is given.
    scheduler : str or distributed.Client, optional
        Address of a Dask scheduler (or a client) to run the cases on.
    progress : bool, optional
        Draw a progress bar on stderr; default: only when stderr is a terminal.

    Returns
    -------
    CampaignResult
        Unpacks as ``n_failed, summary_path``.
    """
    out = Path(out_dir)
    cases_dir = out / "cases"
    cases_dir.mkdir(parents=True, exist_ok=True)
    with _folder_lock(out):
        for stale in cases_dir.glob(".tmp-*"):  # left by a killed run
            shutil.rmtree(stale, ignore_errors=True)
        runner = runner or MasterRunner(campaign.scenario_dir)
        campaign = keyed(campaign, runner)
        _write_json_atomic(out / "campaign.json", {
            "name": campaign.name, "unit": campaign.unit, "skip": campaign.skip,
            "instruments": campaign.instruments, "metrics": campaign.metrics,
            "requirements": campaign.requirements,
            "cases": [{"key": c.key, "label": c.label, "event": c.event,
                       "configuration": c.configuration, "sweep": c.sweep} for c in campaign.cases],
        })
        todo, skipped = [], 0
        for case in campaign.cases:
            if _case_verified(cases_dir, case.key):
                skipped += 1
            else:
                todo.append(case)
        bar = ProgressBar(len(campaign.cases), "campaign", "case", enabled=progress)
        for _ in range(skipped):
            bar.update("ok")
        failures = {}

        def on_done(case, status):
            if status["status"] == "failed":
                failures[case.label] = status["error"]
                if status.get("unpublished"):  # the case never wrote its folder
                    _record_lost(cases_dir, case, status["error"])
            bar.update(status["status"])

        args = (runner, cases_dir, campaign.instruments, campaign.metrics, campaign.skip)
        workers = (os.cpu_count() or 1) if workers is None else int(workers)
        try:
            if scheduler is not None:
                _run_dask(todo, args, scheduler, on_done)
            elif workers <= 0:
                for case in todo:
                    on_done(case, execute_case(case, *args))
            else:
                _run_local(todo, args, workers, on_done)
        finally:
            bar.close()
        summary_path = write_summary(campaign, out)
        return CampaignResult(out, len(campaign.cases), len(todo), skipped, len(failures),
                              summary_path, failures)


class _folder_lock:
    """Exclusive lock on a campaign folder for the life of a campaign run.

    A second campaign (or a run) into the same folder fails at once instead of deleting
    the other's in-progress cases; the lock goes with the process, so a killed
    campaign leaves nothing to clean up.
    """

    def __init__(self, folder: Path):
        self.path = Path(folder) / ".jitterfmu.lock"

    def __enter__(self):
        import fcntl

        self.file = open(self.path, "a+")
        try:
            fcntl.flock(self.file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self.file.close()
            raise CampaignError(f"campaign folder {str(self.path.parent)!r} is in use by "
                                "another campaign or run; wait for it or choose another "
                                "--out") from None
        return self

    def __exit__(self, *exc):
        self.file.close()   # releases the lock
        return False


def _die_with_parent(parent_pid: int, period: float = 1.0) -> None:
    """Pool worker initialiser: exit when the campaign process is gone.

    A killed campaign would otherwise leave its workers running cases and writing into
    its folder.  A daemon thread checks every ``period`` seconds that ``parent_pid``
    still exists (the pool's own parent may be a fork server, so the check names the
    campaign process itself).
    """
    import threading

    def watch():
        while True:
            time.sleep(period)
            try:
                os.kill(parent_pid, 0)
            except ProcessLookupError:
                os._exit(1)
            except PermissionError:
                pass

    threading.Thread(target=watch, name="die-with-parent", daemon=True).start()


def _record_lost(cases_dir: Path, case: Case, error: str) -> None:
    final = cases_dir / case.key
    if _case_status(cases_dir, case.key) is not None:
        return
    tmp = cases_dir / f".tmp-{case.key}-{uuid.uuid4().hex[:8]}"
    tmp.mkdir(parents=True)
    _write_json_atomic(tmp / _STATUS_FILE, {
        "key": case.key, "label": case.label, "event": case.event,
        "configuration": case.configuration, "sweep": case.sweep, "scenario": case.scenario,
        "status": "failed", "error": error, "seconds": None,
    })
    os.replace(tmp, final)


# ----------------------------------------------------------------------------- summary

SUMMARY_SCHEMA = pa.schema([
    ("case", pa.string()), ("key", pa.string()), ("event", pa.string()),
    ("configuration", pa.string()), ("sweep", pa.string()), ("instrument", pa.string()),
    ("axis", pa.string()), ("metric", pa.string()), ("window", pa.float64()),
    ("unit", pa.string()), ("value", pa.float64()), ("requirement", pa.float64()),
    ("margin", pa.float64()), ("margin_ratio", pa.float64()), ("pass", pa.bool_()),
    ("share", pa.float64()), ("note", pa.string()),
])


def summarize(campaign: Campaign, out_dir) -> tuple[pa.Table, pa.Table]:
    """Build the summary and case tables from the case folders.

    Summary rows: one per successful case × instrument × axis × metric × window, plus
    one ``event = "RSS"`` row per configuration × sweep point × instrument × axis ×
    metric × window holding the root-sum-square over the events.  Values, requirements
    and margins are in ``campaign.unit``; ``margin = requirement − value``,
    ``margin_ratio = margin / requirement``, ``pass = value <= requirement`` (null without
    a requirement or for an RSS missing failed events, see ``note``); ``share`` is an
    event's fraction ``value² / RSS²`` of its group's RSS.

    Returns
    -------
    summary : pyarrow.Table
        Columns of :data:`SUMMARY_SCHEMA`.
    cases : pyarrow.Table
        One row per case: key, case, event, configuration, sweep, status, error, seconds.
    """
    cases_dir = Path(out_dir) / "cases"
    scale = ANGLE_UNITS[campaign.unit]
    rows, case_rows = [], []
    groups: dict = {}
    failed_groups: dict = {}
    for case in campaign.cases:
        st = _case_status(cases_dir, case.key) or {"status": "missing", "error": "not run"}
        case_rows.append({"key": case.key, "case": case.label, "event": case.event,
                          "configuration": case.configuration, "sweep": case.sweep,
                          "status": st["status"], "error": st.get("error", ""),
                          "seconds": st.get("seconds")})
        gk = (case.configuration, case.sweep)
        if st["status"] != "ok":
            failed_groups.setdefault(gk, []).append(case.event)
            continue
        mt = pq.read_table(cases_dir / case.key / "metrics.parquet").to_pylist()
        for r in mt:
            v = r["value"] * scale
            rows.append({"case": case.label, "key": case.key, "event": case.event,
                         "configuration": case.configuration, "sweep": case.sweep,
                         "instrument": r["instrument"], "axis": r["axis"],
                         "metric": r["metric"], "window": r["window"], "value": v})
            line = (r["instrument"], r["axis"], r["metric"], r["window"])
            groups.setdefault(gk, {}).setdefault(line, []).append(len(rows) - 1)
    for (cf, sw), lines in groups.items():
        missing = failed_groups.get((cf, sw), [])
        for (inst, axis, metric, window), idx in lines.items():
            total = float(M.rss([rows[i]["value"] for i in idx]))
            for i in idx:
                rows[i]["share"] = rows[i]["value"] ** 2 / total**2 if total > 0 else 0.0
            label = " | ".join(x for x in (RSS_EVENT, cf, sw) if x)
            rows.append({"case": label, "key": "", "event": RSS_EVENT, "configuration": cf,
                         "sweep": sw, "instrument": inst, "axis": axis, "metric": metric,
                         "window": window, "value": total, "share": 1.0,
                         "note": f"incomplete: failed event(s) {missing}" if missing else ""})
    for r in rows:
        req = campaign.requirement(r["instrument"], r["axis"], r["metric"], r["window"])
        r["unit"] = campaign.unit
        r["requirement"] = req
        r.setdefault("note", "")
        if math.isnan(req):
            r["margin"] = r["margin_ratio"] = math.nan
            r["pass"] = None
        else:
            a, ratio = M.margin(r["value"], req)
            r["margin"], r["margin_ratio"] = float(a), float(ratio)
            r["pass"] = None if r["note"] else bool(r["value"] <= req)
    summary = pa.Table.from_pylist(rows, schema=SUMMARY_SCHEMA)
    cases = pa.Table.from_pylist(case_rows, schema=pa.schema([
        ("key", pa.string()), ("case", pa.string()), ("event", pa.string()),
        ("configuration", pa.string()), ("sweep", pa.string()), ("status", pa.string()),
        ("error", pa.string()), ("seconds", pa.float64()),
    ]))
    return summary, cases


def write_summary(campaign: Campaign, out_dir) -> Path:
    """Write summary.parquet/.csv and cases.parquet/.csv atomically; return the summary path."""
    out = Path(out_dir)
    summary, cases = summarize(campaign, out)
    _write_table_atomic(summary, out / "summary.parquet")
    _write_table_atomic(summary, out / "summary.csv", csv=True)
    _write_table_atomic(cases, out / "cases.parquet")
    _write_table_atomic(cases, out / "cases.csv", csv=True)
    return out / "summary.parquet"


def slug(text: str) -> str:
    """File-name friendly form of a label."""
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_") or "x"
