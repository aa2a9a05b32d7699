"""A scenario from its TOML layout: tables parsed one by one into the model."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

from .model import (
    _NAME,
    Action,
    Connection,
    Experiment,
    Instance,
    Scenario,
    ScenarioError,
    _algorithm,
    _check_experiment,
    _expect_table,
    _fmu_kind,
    _freeze,
    _split_ref,
    _time,
    check_keys,
    closest,
)

__all__ = ["scenario_from_dict", "read_toml"]


def _parse_instance(name: str, spec) -> Instance:
    what = f"[fmus.{name}]"
    if not _NAME.match(name):
        raise ScenarioError(f"instance name {name!r} is not an identifier (letters, digits, _)")
    spec = _expect_table(spec, what)
    check_keys(spec, ("fmu", "period", "rate_hz", "parameters"), what)
    if "fmu" not in spec:
        raise ScenarioError(f"{what} has no 'fmu' (an FMU name in fmus/ or a path)")
    if ("period" in spec) == ("rate_hz" in spec):
        raise ScenarioError(f"{what} needs exactly one of 'period' (s) or 'rate_hz' (Hz)")
    if "period" in spec:
        period = _time(spec["period"], f"period of instance {name!r}")
    else:
        rate = _time(spec["rate_hz"], f"rate_hz of instance {name!r}")
        if rate <= 0:
            raise ScenarioError(f"rate_hz of instance {name!r} is {float(rate)!r}; expected > 0")
        period = 1 / rate
    if period <= 0:
        raise ScenarioError(f"period of instance {name!r} is {float(period)!r} s; expected > 0")
    params = _expect_table(spec.get("parameters", {}), f"{what} parameters")
    for key, value in params.items():
        if isinstance(value, (dict, list)):
            raise ScenarioError(
                f"parameter {name}.{key} is a {type(value).__name__}; expected a number, "
                "boolean or string"
            )
    return Instance(name, str(spec["fmu"]), period, _freeze(params))


def _finite(x) -> bool:
    try:
        return math.isfinite(x)
    except OverflowError:  # an int beyond the float range
        return False


def _parse_connection(i: int, spec, names) -> Connection:
    what = f"connection {i + 1}"
    spec = _expect_table(spec, what)
    check_keys(spec, ("from", "to", "gain", "offset"), what)
    for key in ("from", "to"):
        if key not in spec:
            raise ScenarioError(f"{what} has no '{key}' ('instance.variable')")
    src, svar = _split_ref(spec["from"], f"{what} 'from'")
    dst, dvar = _split_ref(spec["to"], f"{what} 'to'")
    for inst, ref in ((src, spec["from"]), (dst, spec["to"])):
        if inst not in names:
            raise ScenarioError(
                f"{what} ({spec['from']} -> {spec['to']}) refers to unknown instance "
                f"{inst!r}{closest(inst, names)}"
            )
    gain, offset = spec.get("gain", 1.0), spec.get("offset", 0.0)
    for key, v in (("gain", gain), ("offset", offset)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not _finite(v):
            raise ScenarioError(f"{what} {key} is {v!r}; expected a finite number")
    return Connection(src, svar, dst, dvar, float(gain), float(offset))


def _parse_action(i: int, spec, names) -> Action:
    what = f"action {i + 1}"
    spec = _expect_table(spec, what)
    check_keys(spec, ("time", "set"), what)
    if "time" not in spec or "set" not in spec:
        raise ScenarioError(f"{what} needs 'time' (s) and 'set' (a table of values)")
    t = _time(spec["time"], f"{what} time")
    values = {}
    for ref, v in _expect_table(spec["set"], f"{what} set").items():
        inst, var = _split_ref(ref, f"{what} target")
        if inst not in names:
            raise ScenarioError(f"{what} sets {ref!r} of unknown instance {inst!r}"
                                f"{closest(inst, names)}")
        values[(inst, var)] = v
    return Action(t, _freeze(values))


def scenario_from_dict(data: dict, base_dir=None, source: str = "<dict>") -> Scenario:
    """Build a Scenario from plain data (the parsed TOML layout).

    Parameters
    ----------
    data : dict
        Tables ``experiment``, ``fmus``, ``connections``, ``actions``, ``record``.
    base_dir : path-like, optional
        Folder against which relative FMU names are resolved.
    source : str
        Name used in error messages.

    Returns
    -------
    Scenario
    """
    data = _expect_table(data, "scenario")
    check_keys(data, ("experiment", "fmus", "connections", "actions", "record"), source)
    exp = _expect_table(data.get("experiment", {}), "[experiment]")
    check_keys(exp, ("start", "stop", "output_interval", "algorithm", "fmu_kind"),
               "[experiment]")
    for key in ("stop", "output_interval"):
        if key not in exp:
            raise ScenarioError(f"[experiment] has no '{key}' (s)")
    experiment = Experiment(
        stop=_time(exp["stop"], "experiment.stop"),
        output_interval=_time(exp["output_interval"], "experiment.output_interval"),
        algorithm=_algorithm(exp.get("algorithm", "gauss-seidel")),
        start=_time(exp.get("start", 0), "experiment.start"),
        fmu_kind=_fmu_kind(exp.get("fmu_kind", "native")),
    )
    _check_experiment(experiment)
    fmus = _expect_table(data.get("fmus", {}), "[fmus]")
    if not fmus:
        raise ScenarioError(f"{source} defines no FMU instances ([fmus.NAME] tables)")
    instances = tuple(_parse_instance(n, s) for n, s in fmus.items())
    names = [i.name for i in instances]
    conns = data.get("connections", [])
    if not isinstance(conns, list):
        raise ScenarioError("connections must be an array of tables ([[connections]])")
    connections = tuple(_parse_connection(i, c, names) for i, c in enumerate(conns))
    acts = data.get("actions", [])
    if not isinstance(acts, list):
        raise ScenarioError("actions must be an array of tables ([[actions]])")
    actions = tuple(sorted((_parse_action(i, a, names) for i, a in enumerate(acts)),
                           key=lambda a: a.time))
    rec = _expect_table(data.get("record", {}), "[record]")
    check_keys(rec, ("variables",), "[record]")
    variables = rec.get("variables", [])
    if not isinstance(variables, list):
        raise ScenarioError("record.variables must be an array of 'instance.variable' strings")
    for ref in variables:
        inst, _ = _split_ref(ref, "recorded variable")
        if inst not in names:
            raise ScenarioError(f"recorded variable {ref!r} names unknown instance {inst!r}"
                                f"{closest(inst, names)}")
    if len(set(variables)) != len(variables):
        dup = sorted({v for v in variables if variables.count(v) > 1})
        raise ScenarioError(f"record.variables lists {dup} more than once")
    return Scenario(
        experiment, instances, connections, actions, tuple(variables),
        Path(base_dir) if base_dir is not None else None, source,
    )


def read_toml(path, base_dir=None) -> Scenario:
    """Read a TOML scenario file.

    Parameters
    ----------
    path : path-like
        The ``.toml`` file.
    base_dir : path-like, optional
        Folder for relative FMU names (default: the file's folder).

    Returns
    -------
    Scenario
    """
    path = Path(path)
    if path.is_dir():
        raise ScenarioError(f"scenario {str(path)!r} is a folder; expected a TOML scenario "
                            "file or an SSP archive")
    if not path.is_file():
        raise ScenarioError(f"scenario file {str(path)!r} does not exist")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise ScenarioError(f"scenario file {str(path)!r} is not text (not UTF-8); expected "
                            "a TOML scenario file or an SSP archive") from None
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"scenario file {str(path)!r} is not valid TOML: {exc}") from None
    try:
        return scenario_from_dict(data, base_dir or path.parent, str(path))
    except ScenarioError as exc:
        raise ScenarioError(f"{path}: {exc}") from None
