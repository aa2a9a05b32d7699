"""A scenario from its TOML layout: tables parsed one by one into the model."""

from __future__ import annotations

import math
import os
import tomllib
from pathlib import Path

from fmutools.archive import PATH_CHARS, short_repr

from ..schema import keys
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
    duplicates,
)

__all__ = ["MAX_FILE_MIB", "load_toml_file", "read_scenario_bytes", "read_toml",
           "scenario_from_dict"]


def _parse_instance(name: str, spec) -> Instance:
    what = f"[fmus.{name}]"
    if not _NAME.match(name):
        raise ScenarioError(f"instance name {name!r} is not an identifier (letters, digits, _)")
    spec = _expect_table(spec, what)
    check_keys(spec, keys("[fmus.NAME]"), what)
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
    check_keys(spec, keys("[[connections]]"), what)
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
    check_keys(spec, keys("[[actions]]"), what)
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
    check_keys(data, keys("scenario"), source)
    exp = _expect_table(data.get("experiment", {}), "[experiment]")
    check_keys(exp, keys("[experiment]"), "[experiment]")
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
    names = {i.name: None for i in instances}   # a set in declaration order
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
    check_keys(rec, keys("[record]"), "[record]")
    variables = rec.get("variables", [])
    if not isinstance(variables, list):
        raise ScenarioError("record.variables must be an array of 'instance.variable' strings")
    for ref in variables:
        inst, _ = _split_ref(ref, "recorded variable")
        if inst not in names:
            raise ScenarioError(f"recorded variable {ref!r} names unknown instance {inst!r}"
                                f"{closest(inst, names)}")
    dup = duplicates(variables)
    if dup:
        shown = ", ".join(short_repr(v) for v in dup[:5])
        more = f" and {len(dup) - 5} more" if len(dup) > 5 else ""
        raise ScenarioError(f"record.variables lists {shown}{more} more than once; list "
                            "each variable once")
    return Scenario(
        experiment, instances, connections, actions, tuple(variables),
        Path(base_dir) if base_dir is not None else None, source,
    )


#: Largest scenario or campaign file read (MiB), unless ``$JITTERFMU_MAX_SCENARIO_MIB``
#: says otherwise: a scenario lists FMUs, connections and actions, not data.
MAX_FILE_MIB = 16
MAX_FILE_ENV = "JITTERFMU_MAX_SCENARIO_MIB"


def read_scenario_bytes(path: Path, what: str, error: type = ScenarioError) -> bytes:
    """The bytes of a scenario file (TOML, or an SSP's SystemStructure.ssd) within the
    size limit, :data:`MAX_FILE_MIB` MiB unless ``$JITTERFMU_MAX_SCENARIO_MIB`` says
    otherwise; one sentence naming the file, its size and the limit if it is larger.

    Parameters
    ----------
    path : Path
    what : str
        How the message names the file (``"scenario file 'a.toml'"``).
    error : exception class

    Returns
    -------
    bytes
    """
    raw = os.environ.get(MAX_FILE_ENV)
    try:
        limit = float(raw) if raw else MAX_FILE_MIB
    except ValueError:
        raise error(f"{MAX_FILE_ENV} is {short_repr(raw)}; expected a size in MiB") from None
    size = path.stat().st_size
    if size > limit * (1 << 20):
        raise error(f"{what} is {size / (1 << 20):.1f} MiB, above the "
                    f"limit of {limit:g} MiB for a scenario (it lists FMUs, connections and "
                    "actions; data belongs in an FMU's resources); to read it anyway, set "
                    f"{MAX_FILE_ENV}")
    return path.read_bytes()


def load_toml_file(path, what: str = "scenario file", error: type = ScenarioError) -> dict:
    """The tables of a TOML file, or one sentence naming the file and what is wrong.

    The file must exist, be at most :data:`MAX_FILE_MIB` MiB (``$JITTERFMU_MAX_SCENARIO_MIB``
    raises it), be UTF-8 text and valid TOML nested no deeper than Python can read.

    Parameters
    ----------
    path : path-like
        The ``.toml`` file.
    what : str
        How messages name it (``"scenario file"``, ``"base scenario"``).
    error : exception class
        Raised with the sentence (a campaign passes its own).

    Returns
    -------
    dict
    """
    path = Path(path)
    shown = short_repr(str(path), PATH_CHARS)
    try:
        if path.is_dir():
            raise error(f"{what} {shown} is a folder; expected a TOML scenario file or an "
                        "SSP archive")
        if not path.is_file():
            raise error(f"{what} {shown} does not exist")
        data = read_scenario_bytes(path, f"{what} {shown}", error)
    except OSError as exc:
        raise error(f"{what} {shown} cannot be read: {exc.strerror}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise error(f"{what} {shown} is not text (not UTF-8) from byte {exc.start} on "
                    f"line {line}; expected a TOML scenario file saved as UTF-8, or an SSP "
                    "archive") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{what} {shown} is not valid TOML: {exc}") from None
    except RecursionError:
        raise error(f"{what} {shown} nests arrays or tables deeper than can be read; "
                    "flatten it") from None


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
    data = load_toml_file(path)
    try:
        return scenario_from_dict(data, base_dir or path.parent, str(path))
    except ScenarioError as exc:
        name = str(path) if len(str(path)) <= PATH_CHARS else short_repr(str(path))
        raise ScenarioError(f"{name}: {exc}") from None
