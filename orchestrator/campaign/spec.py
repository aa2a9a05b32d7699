"""The campaign file, parsed table by table into a :class:`CampaignSpec`.

Each table (``[campaign]``, ``[[events]]``, ``[[configurations]]``, ``[[sweeps]]``,
``[[instruments]]``, ``[[metrics]]``, ``[[requirements]]``) has its own small parser that
checks its keys and values and names the culprit in one sentence (:class:`CampaignError`).
The tables are checked in that order, and the overrides last, case by case, so the error
reported for a file with several mistakes is the first one a reader would meet.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from fmukit.units import ARCSEC_PER_RAD, DEG_PER_RAD
from fmutools.archive import PATH_CHARS, short_repr

from ..scenario import closest, load_toml_file
from ..schema import keys
from .spec_base import ENGINES, CampaignError, check_table_keys
from .spec_uncertainty import parse_uncertainty

#: Factor from rad to each supported reporting unit.
ANGLE_UNITS = {
    "rad": 1.0,
    "mrad": 1e3,
    "urad": 1e6,
    "deg": DEG_PER_RAD,
    "arcsec": ARCSEC_PER_RAD,
}
#: Metric kinds of a campaign and what their window (s) means; each gives one number
#: per record, its largest value over the record (the ECSS temporal interpretation).
METRIC_KINDS = {
    "peak_to_peak": "windowed peak-to-peak jitter over T (s)",
    "rms_jitter": "RMS deviation from the window mean over T (s)",
    "stability": "RMS change across a lag Ts (s)",
    "rms": "RMS about the record mean (no window)",
    "ape": "ECSS absolute performance error: largest |e| (no window)",
    "mpe": "ECSS mean performance error: largest |mean of e| over windows T (s)",
    "rpe": "ECSS relative performance error: largest |e - its window mean|, windows T (s)",
    "pde": "ECSS performance drift error: largest |difference of the means of two "
           "windows T (s) one window apart|",
}
#: Metric kinds that take no window.
WINDOWLESS = ("rms", "ape")
#: Event name of the summary rows holding the RSS over the events.
RSS_EVENT = "RSS"
#: The lowest top speed of a wheel sweep (rpm): below it the wheel stands still.
MIN_RPM = 1e-3
#: The most cases a campaign expands to (each holds its scenario in memory and a folder).
MAX_CASES = 100_000
# Valid keys of every table of a campaign file: the key reference's (orchestrator.schema).
_KEYS = keys("campaign")
_CAMPAIGN_KEYS = keys("[campaign]")
_ITEM_KEYS = {name: keys(f"[[{name}]]") for name in (
    "events", "configurations", "sweeps", "instruments", "metrics", "requirements",
    "wheel_sweeps")}


@dataclass(frozen=True)
class Variant:
    """An event or a configuration: a name and its parameter overrides.

    Attributes
    ----------
    name : str
    overrides : dict of str to value
        ``{"instance.variable": start value}``.
    """

    name: str
    overrides: dict


@dataclass(frozen=True)
class CampaignSpec:
    """A campaign file, checked, before its cases are expanded.

    Attributes
    ----------
    name : str
    scenario : dict
        Base scenario data (the TOML layout) with the campaign's experiment settings and
        absolute paths to ``.fmu`` files.
    events, configurations : tuple of Variant
    sweeps : tuple of tuple of (str, value)
        Per sweep, its ``(parameter, value)`` points.
    instruments, metrics, requirements, unit, skip, base_dir, scenario_dir, source
        As in :class:`~orchestrator.campaign.Campaign`.
    overrides : tuple of (str, str, tuple)
        Every ``instance.variable`` the campaign sets, with the field that sets it
        (``"sweep 1 parameter 'sc.mass'"``) and the values, for a check against the FMUs.
    """

    name: str
    scenario: dict
    events: tuple
    configurations: tuple
    sweeps: tuple
    instruments: dict
    metrics: tuple
    requirements: tuple
    unit: str
    skip: float
    base_dir: Path
    scenario_dir: Path
    engine: str = "cosim"
    verify: int = 2
    wheel_sweeps: tuple = ()
    uncertainty: dict | None = None
    source: str = "campaign data"
    overrides: tuple = ()


@dataclass(frozen=True)
class WheelSweepSpec:
    """A ``[[wheel_sweeps]]`` entry: a wheel source swept over its speed range.

    Attributes
    ----------
    name : str
    instance : str
        The wheel-imbalance source instance.
    overrides : dict
        Set with every configuration's (e.g. the wheel's preset).
    rpm : tuple of float
        ``(low, high)`` speed range (rpm).
    points : int
        Speeds, evenly spaced, ends included.
    open : tuple of str
        Instances taken out of the loop (e.g. a slow ACS whose loop is unstable).
    """

    name: str
    instance: str
    overrides: dict
    rpm: tuple
    points: int
    open: tuple = ()


def parse_spec(data: Mapping, base_dir=None, source: str = "campaign data") -> CampaignSpec:
    """Check campaign data (the TOML layout) table by table.

    Parameters
    ----------
    data : mapping
        Tables ``campaign``, ``events``, ``configurations``, ``sweeps``, ``instruments``,
        ``metrics``, ``requirements``.  ``campaign.scenario`` is a path to the base
        scenario TOML or an inline table (the scenario layout).
    base_dir : path-like, optional
        Folder for relative paths (default: current folder).
    source : str
        What the data came from (``"campaign file 'c.toml'"``), for later messages.

    Returns
    -------
    CampaignSpec

    Raises
    ------
    CampaignError
        Naming the table, the entry and what was expected.
    """
    base_dir = Path(base_dir or Path.cwd()).resolve()
    head = data.get("campaign")
    if not isinstance(head, dict):
        raise CampaignError("campaign file has no [campaign] table")
    check_table_keys(data, _KEYS, "campaign file")
    check_table_keys(head, _CAMPAIGN_KEYS, "[campaign]")
    name = str(head.get("name", "campaign"))
    scenario, scenario_dir = _base_scenario(head, name, base_dir)
    unit = str(head.get("unit", "arcsec"))
    if unit not in ANGLE_UNITS:
        raise CampaignError(f"[campaign] unit is {unit!r}; expected one of {sorted(ANGLE_UNITS)}")
    skip = head.get("skip", 0.0)
    if isinstance(skip, bool) or not isinstance(skip, (int, float)):
        raise CampaignError(f"[campaign] skip is {short_repr(skip)}; expected a time in s "
                            "(a number >= 0), e.g. skip = 0.5")
    skip = float(skip)
    if not skip >= 0:
        raise CampaignError(f"[campaign] skip is {skip!r} s; expected >= 0")
    record = _record_length(scenario["experiment"], skip)

    engine = str(head.get("engine", "cosim"))
    if engine not in ENGINES:
        raise CampaignError(f"[campaign] engine is {engine!r}; expected one of {list(ENGINES)}")
    verify = head.get("verify", 2)
    if isinstance(verify, bool) or not isinstance(verify, int) or verify < 0:
        raise CampaignError(f"[campaign] verify is {verify!r}; expected a whole number of "
                            "cases >= 0 to cross-check by co-simulation")

    events = data.get("events", [{"name": "baseline"}])
    configurations = data.get("configurations", [{"name": "baseline"}])
    event_names = _named(events, "events")
    _named(configurations, "configurations")
    if RSS_EVENT in event_names:
        raise CampaignError(f"event name {RSS_EVENT!r} is reserved for the RSS total")
    sweeps = _sweeps(data.get("sweeps", []))
    instruments, shorthand = _instruments(data.get("instruments"))
    # the default metric is not checked against the record: nobody asked for its window
    metrics = _metrics(data.get("metrics", [{"kind": "peak_to_peak", "windows": [1.0]}]),
                       record if "metrics" in data else None, skip)
    requirements = _requirements(data.get("requirements", []), shorthand, instruments, metrics)
    n_cases = len(events) * len(configurations) * math.prod(len(sw) for sw in sweeps)
    if n_cases > MAX_CASES:
        raise CampaignError(f"the campaign expands to {n_cases} cases (events x configurations "
                            f"x sweep values), more than the {MAX_CASES} it holds; split it into "
                            "campaigns of fewer values")
    events, configurations = _variants(events, configurations, sweeps, scenario["fmus"])
    wheel = _wheel_sweeps(data.get("wheel_sweeps", []), scenario["fmus"])
    if not configurations or not (events or wheel):
        empty = "configurations" if not configurations else "events"
        raise CampaignError(f"[[{empty}]] is empty, so the campaign would run nothing; give "
                            f"at least one entry, or leave [[{empty}]] out for one baseline")
    unc = parse_uncertainty(data.get("uncertainty"), scenario["fmus"])
    overrides = tuple(
        [(f"event {v.name!r} override {k!r}", k, (x,))
         for v in events for k, x in v.overrides.items()]
        + [(f"configuration {v.name!r} override {k!r}", k, (x,))
           for v in configurations for k, x in v.overrides.items()]
        + [(f"sweep {i + 1} parameter {sweep[0][0]!r}", sweep[0][0], tuple(x for _, x in sweep))
           for i, sweep in enumerate(sweeps)])
    return CampaignSpec(name, scenario, events, configurations, sweeps, instruments,
                        tuple(metrics), requirements, unit, skip, base_dir, scenario_dir,
                        engine, verify, wheel, unc, source, overrides)


def read_spec(path, uncertainty=None, samples=None) -> CampaignSpec:
    """Read and check a campaign TOML file (see :mod:`orchestrator.campaign`).

    Parameters
    ----------
    path : path-like
        The campaign file.
    uncertainty : path-like, optional
        A TOML file holding one ``[uncertainty]`` table, which replaces the campaign
        file's (the same budget under an uncertainty of its own, without a copy of the
        campaign).
    samples : int, optional
        The sample count, in place of the table's ``samples``.

    Returns
    -------
    CampaignSpec

    Raises
    ------
    CampaignError
        One sentence naming the file, the table and what is wrong.
    """
    path = Path(path)
    data = load_toml_file(path, "campaign file", CampaignError)
    source = f"campaign file {str(path)!r}"
    if uncertainty is not None:
        shown = short_repr(str(uncertainty), PATH_CHARS)
        extra = load_toml_file(uncertainty, "uncertainty file", CampaignError)
        if set(extra) != {"uncertainty"}:
            other = ", ".join(repr(k) for k in sorted(set(extra) - {"uncertainty"}))
            held = ("nothing" if not extra else f"{other} besides [uncertainty]"
                    if "uncertainty" in extra else f"{other} and no [uncertainty] table")
            raise CampaignError(f"uncertainty file {shown} holds {held}; expected one "
                                "[uncertainty] table (the rest of the campaign stays in the "
                                "campaign file)")
        data = {**data, "uncertainty": extra["uncertainty"]}
        source += f" with the [uncertainty] of {shown}"
    if samples is not None:
        if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
            raise CampaignError(f"the sample count is {samples!r}; expected a whole number "
                                ">= 1")
        if "uncertainty" not in data:
            raise CampaignError(f"{source} has no [uncertainty] table, so a sample count "
                                "has nothing to count; add one, or give it in a file of its "
                                "own (jitterfmu campaign --uncertainty FILE)")
        if isinstance(data["uncertainty"], dict):   # else parse_uncertainty says what
            data = {**data, "uncertainty": {**data["uncertainty"], "samples": samples}}
    try:
        return parse_spec(data, path.parent, source)
    except CampaignError as exc:
        raise CampaignError(f"{source}: {exc}") from None


# ----------------------------------------------------------------------------- tables


def _base_scenario(head: dict, name: str, base_dir: Path) -> tuple[dict, Path]:
    """The ``[campaign]`` table's base scenario data and its folder.

    FMU names stay as written; paths to ``.fmu`` files are made absolute so that cases
    run anywhere.  ``stop``, ``output_interval`` and ``algorithm`` of ``[campaign]``
    replace those of the scenario's ``[experiment]``.
    """
    scen = head.get("scenario")
    if isinstance(scen, str):
        path = (base_dir / scen).resolve()
        if not path.is_file():
            raise CampaignError(f"base scenario {str(path)!r} of campaign {name!r} does not exist")
        scenario = load_toml_file(path, "base scenario", CampaignError)
        scenario_dir = path.parent
    elif isinstance(scen, dict):
        scenario, scenario_dir = json.loads(json.dumps(scen)), base_dir
    else:
        raise CampaignError("[campaign] scenario must be a path to a TOML file or a table")
    if not isinstance(scenario.get("fmus"), dict) or not scenario["fmus"]:
        raise CampaignError(f"base scenario of campaign {name!r} has no [fmus.NAME] tables")
    for spec in scenario["fmus"].values():
        fmu = str(spec.get("fmu", ""))
        if fmu.endswith(".fmu") and not Path(fmu).is_absolute():
            spec["fmu"] = str((scenario_dir / fmu).resolve())
    exp = scenario.setdefault("experiment", {})
    for k in ("stop", "output_interval", "algorithm"):
        if k in head:
            exp[k] = head[k]
    return scenario, scenario_dir


def _sweeps(items) -> tuple:
    """``[[sweeps]]``: per sweep, its ``(parameter, value)`` points."""
    _table_list(items, "sweeps", _ITEM_KEYS["sweeps"])
    sweeps = []
    for i, s in enumerate(items):
        if not isinstance(s, dict) or "parameter" not in s or not s.get("values"):
            raise CampaignError(f"sweep {i + 1} needs 'parameter' and a non-empty 'values'")
        if not isinstance(s["values"], list):
            raise CampaignError(f"sweep {i + 1} values is {short_repr(s['values'])}; expected "
                                "a list, e.g. values = [0.1, 0.2]")
        parameter = str(s["parameter"])
        inst, _, var = parameter.partition(".")
        if not inst or not var:
            raise CampaignError(f"sweep {i + 1} parameter {parameter!r} must have the form "
                                "'instance.variable'")
        first = next((j for j, sw in enumerate(sweeps) if sw[0][0] == parameter), None)
        if first is not None:
            raise CampaignError(f"sweeps {first + 1} and {i + 1} both sweep {parameter!r}, "
                                "and a case takes one value of it; give one sweep all its "
                                "values")
        sweeps.append(tuple((parameter, v) for v in s["values"]))
    return tuple(sweeps)


def _instruments(items) -> tuple[dict, list]:
    """``[[instruments]]``: the axes of each, and requirements given as a shorthand."""
    if not isinstance(items, list) or not items:
        raise CampaignError("campaign has no [[instruments]] (name and axes of recorded LOS)")
    _table_list(items, "instruments", _ITEM_KEYS["instruments"])
    instruments, shorthand = {}, []
    for i, it in enumerate(items):
        if not isinstance(it, dict) or "name" not in it or not isinstance(it.get("axes"), dict):
            raise CampaignError(f"instrument {i + 1} needs 'name' and 'axes' = {{axis = var}}")
        if it["name"] in instruments:
            raise CampaignError(f"instrument {it['name']!r} is defined twice")
        instruments[str(it["name"])] = {str(a): str(v) for a, v in it["axes"].items()}
        if "requirement" in it:  # shorthand: one value for every axis, metric and window
            shorthand.append({"instrument": str(it["name"]), "value": it["requirement"]})
    return instruments, shorthand


def _record_length(experiment: dict, skip: float) -> float | None:
    """Seconds of record the metrics see (run length less ``skip``); None if unknown.

    The run's times are checked with the scenario; only numbers are used here.
    """
    start, stop = experiment.get("start", 0.0), experiment.get("stop")
    if not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
               for x in (start, stop)) or stop <= start:
        return None
    if skip >= stop - start:
        raise CampaignError(f"[campaign] skip is {skip!r} s, which leaves no record of the "
                            f"{stop - start!r} s run; expected skip < stop - start")
    return stop - start - skip


def _metrics(items, record: float | None, skip: float) -> list:
    """``[[metrics]]``: ``(kind, window)`` pairs, one per window (``None`` for ``rms``).

    A window (or lag) must be a positive time no longer than the record the metrics see
    (``record`` s after the ``skip``); a longer one would measure the whole record.
    """
    _table_list(items, "metrics", _ITEM_KEYS["metrics"])
    metrics = []
    for i, m in enumerate(items):
        kind = m.get("kind") if isinstance(m, dict) else None
        if kind not in METRIC_KINDS:
            raise CampaignError(
                f"metric {i + 1} kind is {kind!r}; expected one of {sorted(METRIC_KINDS)}"
            )
        if kind in WINDOWLESS:
            metrics.append((kind, None))
            continue
        windows = m.get("windows", [m["window"]] if "window" in m else [])
        if not isinstance(windows, list):
            raise CampaignError(f"metric {i + 1} ({kind}) windows is {windows!r}; expected a "
                                "list of times (s), e.g. [1.0]")
        if not windows:
            raise CampaignError(f"metric {i + 1} ({kind}) needs 'windows' (s)")
        for w in windows:
            if isinstance(w, bool) or not (isinstance(w, (int, float)) and w > 0):
                raise CampaignError(f"metric {i + 1} ({kind}) window {w!r} is not a positive "
                                    "time (s)")
            if record is not None and w > record * (1 + 1e-9):
                raise CampaignError(f"metric {i + 1} ({kind}) window {w!r} s is longer than "
                                    f"the record ({record:g} s after the {skip:g} s skip); "
                                    "shorten the window or lengthen [campaign] stop")
            metrics.append((kind, float(w)))
    return metrics


def _requirements(items, shorthand: list, instruments: dict, metrics: list) -> tuple:
    """``[[requirements]]`` then the instruments' shorthand ones, each checked."""
    explicit = _table_list(items, "requirements", _ITEM_KEYS["requirements"])
    reqs = []
    for i, r in enumerate(list(explicit) + shorthand):
        if "instrument" not in r or "value" not in r:
            raise CampaignError(f"requirement {i + 1} needs 'instrument' and 'value'")
        if r["instrument"] not in instruments:
            raise CampaignError(
                f"requirement {i + 1} names unknown instrument {r['instrument']!r} "
                f"(instruments: {sorted(instruments)})"
            )
        _check_requirement(r, i + 1, instruments[r["instrument"]], metrics)
        reqs.append(dict(r))
    return tuple(reqs)


def _check_requirement(r: dict, number: int, axes: dict, metrics: list) -> None:
    """A requirement's axis, metric and window must match something, else it never applies."""
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


def _variants(events: list, configurations: list, sweeps: tuple, fmus: dict) -> tuple:
    """Events and configurations with their overrides checked, in case order.

    Every override (and swept parameter) must name an instance of the base scenario.
    The pairs are checked in the order the cases are expanded, so the error is the
    first case's.
    """
    swept = {parameter: None for sweep in sweeps for parameter, _ in sweep}
    ov_events, ov_configurations = {}, {}

    def check(keys):
        for key in keys:
            inst, _ = key.split(".", 1)
            if inst not in fmus:
                raise CampaignError(
                    f"override {key!r} names instance {inst!r}, which the base scenario does "
                    f"not have (instances: {sorted(fmus)})"
                )

    def not_swept(ov, what):
        both = [k for k in ov if k in swept]
        if both:
            raise CampaignError(f"{what} sets {both[0]!r}, which a [[sweeps]] entry sweeps, so "
                                "its cases would run with the swept value under its name; "
                                "drop the override or the sweep")
        return ov

    for (i, ev), (j, cf) in itertools.product(enumerate(events), enumerate(configurations)):
        ov_e = ov_events[i] = not_swept(_overrides(ev, f"event {ev['name']!r}"),
                                        f"event {ev['name']!r}")
        ov_c = ov_configurations[j] = not_swept(_overrides(cf, f"configuration {cf['name']!r}"),
                                                f"configuration {cf['name']!r}")
        check({**ov_c, **ov_e, **swept})
    # without events the configurations still carry the wheel sweeps' overrides
    for j, cf in enumerate(configurations):
        if j not in ov_configurations:
            ov_configurations[j] = _overrides(cf, f"configuration {cf['name']!r}")
            check(ov_configurations[j])
    return (tuple(Variant(str(e["name"]), ov_events.get(i, {})) for i, e in enumerate(events)),
            tuple(Variant(str(c["name"]), ov_configurations.get(j, {}))
                  for j, c in enumerate(configurations)))


def _wheel_sweeps(items, fmus: dict) -> tuple:
    """``[[wheel_sweeps]]``: each checked, with its instance and overrides in the scenario."""
    _table_list(items, "wheel_sweeps", _ITEM_KEYS["wheel_sweeps"])
    out = []
    for i, w in enumerate(items):
        what = f"wheel sweep {i + 1}"
        inst = w.get("instance")
        if not isinstance(inst, str) or inst not in fmus:
            raise CampaignError(f"{what} instance is {inst!r}"
                                f"{closest(inst, fmus) if isinstance(inst, str) else ''}; "
                                "expected a source instance of the base scenario (instances: "
                                f"{', '.join(sorted(fmus))})")
        rpm = w.get("rpm", [0.0, 6000.0])
        if not (isinstance(rpm, list) and len(rpm) == 2
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in rpm)
                and 0 <= rpm[0] < rpm[1] and math.isfinite(rpm[1])):
            raise CampaignError(f"{what} rpm is {rpm!r}; expected [low, high] with "
                                "0 <= low < high (rpm)")
        period = fmus[inst].get("period")
        top = 30.0 / period if isinstance(period, (int, float)) and period > 0 else math.inf
        if not MIN_RPM <= rpm[1] < top:
            raise CampaignError(f"{what} rpm is {rpm!r}; the top speed must lie between "
                                f"{MIN_RPM} rpm and {top:.6g} rpm, where the wheel's turn rate "
                                f"reaches the Nyquist frequency of {inst}'s period; sweep a "
                                "wheel's real speed range")
        points = w.get("points", 500)
        if isinstance(points, bool) or not isinstance(points, int) or points < 2:
            raise CampaignError(f"{what} points is {points!r}; expected a whole number >= 2")
        opened = w.get("open", [])
        if not isinstance(opened, list) or any(o not in fmus for o in opened):
            bad = next((o for o in opened if isinstance(o, str) and o not in fmus), None) \
                if isinstance(opened, list) else None
            raise CampaignError(f"{what} open is {opened!r}"
                                f"{closest(bad, fmus) if bad else ''}; expected a list of "
                                "instances of the base scenario (instances: "
                                f"{', '.join(sorted(fmus))})")
        overrides = _overrides(w, what)
        for key in overrides:
            if key.split(".", 1)[0] not in fmus:
                raise CampaignError(f"{what} override {key!r} names an instance the base "
                                    f"scenario does not have"
                                    f"{closest(key.split('.', 1)[0], fmus)}")
        out.append(WheelSweepSpec(str(w.get("name", inst)), inst, overrides,
                                  (float(rpm[0]), float(rpm[1])), points, tuple(opened)))
    return tuple(out)


def _overrides(item, what: str) -> dict:
    ov = item.get("overrides", {})
    if not isinstance(ov, dict):
        raise CampaignError(f"{what} overrides must be a table of 'instance.variable' = value")
    for k in ov:
        if "." not in k:
            raise CampaignError(f"{what} override {k!r} must have the form 'instance.variable'")
    return dict(ov)


# ----------------------------------------------------------------------------- helpers


def _table_list(items, what: str, allowed) -> list:
    """Check an array of tables ``[[what]]`` and the keys of each of its tables."""
    if not isinstance(items, list):
        raise CampaignError(f"{what} must be an array of tables ([[{what}]])")
    for i, it in enumerate(items):
        if not isinstance(it, dict):
            raise CampaignError(f"[[{what}]] entry {i + 1} is a {type(it).__name__}; expected "
                                "a table")
        label = f" ({it['name']!r})" if isinstance(it.get("name"), str) else ""
        check_table_keys(it, allowed, f"[[{what}]] entry {i + 1}{label}")
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
