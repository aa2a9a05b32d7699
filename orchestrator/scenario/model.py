"""The scenario model: which FMUs, at which rates, wired how, recording what.

Frozen dataclasses and the checks that need no FMU (names, signs, times).  Reading
them from TOML is :mod:`.toml`, from SSP :mod:`.ssp`; checks against the FMUs' model
descriptions are :func:`orchestrator.cosim.prepare`.
"""

from __future__ import annotations

import difflib
import hashlib
import json
import re
import tomllib
from dataclasses import dataclass, field, replace
from fractions import Fraction
from pathlib import Path
from types import MappingProxyType

from fmutools import FMU_KINDS
from fmutools.archive import short_repr

from ..timebase import TimebaseError, to_fraction

__all__ = [
    "Action",
    "Connection",
    "Experiment",
    "Instance",
    "Scenario",
    "ScenarioError",
    "check_keys",
    "closest",
    "duplicates",
    "parse_override",
]

ALGORITHMS = ("gauss-seidel", "jacobi")
#: Which build of the suite's FMUs a scenario runs (:data:`fmutools.FMU_KINDS`): the
#: self-contained C FMUs, or the Python (pythonfmu) ones in an FMU folder's ``python/``.
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


class ScenarioError(ValueError):
    """A scenario that is malformed or refers to something that does not exist."""


def closest(name: str, candidates) -> str:
    """Return a ' (did you mean ...?)' hint listing the closest candidates, or ''.

    Parameters
    ----------
    name : str
        The unknown name.
    candidates : iterable of str
        Known names; up to three close ones are listed.

    Returns
    -------
    str
        Hint to append to an error message.
    """
    matches = difflib.get_close_matches(str(name), list(candidates), n=3, cutoff=0.5)
    if not matches:
        return ""
    return " (did you mean " + " or ".join(repr(m) for m in matches) + "?)"


def duplicates(items) -> list:
    """The items that occur more than once, each once, in order of their second
    occurrence (one pass with a set: linear in ``len(items)``).

    Parameters
    ----------
    items : iterable of hashable

    Returns
    -------
    list
    """
    seen, dup = set(), {}
    for item in items:
        if item in seen:
            dup[item] = None
        else:
            seen.add(item)
    return list(dup)


def _freeze(d) -> MappingProxyType:
    return MappingProxyType(dict(d))


@dataclass(frozen=True)
class Experiment:
    """Run settings.

    Attributes
    ----------
    stop : Fraction
        Stop time (s).
    output_interval : Fraction
        Interval between recorded rows (s).
    algorithm : str
        ``"gauss-seidel"`` or ``"jacobi"``.
    start : Fraction
        Start time (s).
    fmu_kind : str
        ``"native"`` (default): FMU names resolve to the native C FMUs of an FMU folder;
        ``"python"``: to the Python FMUs in its ``python/`` subfolder first.
    """

    stop: Fraction
    output_interval: Fraction
    algorithm: str = "gauss-seidel"
    start: Fraction = Fraction(0)
    fmu_kind: str = "native"


@dataclass(frozen=True)
class Instance:
    """One FMU instance.

    Attributes
    ----------
    name : str
        Instance name, unique in the scenario.
    fmu : str
        FMU name (looked up as ``fmus/<name>.fmu``) or path to an ``.fmu`` file.
    period : Fraction
        Communication period (s).
    parameters : mapping of str to value
        Start values set before initialisation (float, int, bool or str).
    """

    name: str
    fmu: str
    period: Fraction
    parameters: MappingProxyType = field(default_factory=lambda: _freeze({}))


@dataclass(frozen=True)
class Connection:
    """A signal from an output of one instance to an input of another.

    The input receives ``gain * output + offset`` (SSP linear transformation).
    """

    source: str
    source_var: str
    target: str
    target_var: str
    gain: float = 1.0
    offset: float = 0.0

    @property
    def start(self) -> str:
        """The source as ``instance.variable``."""
        return f"{self.source}.{self.source_var}"

    @property
    def end(self) -> str:
        """The target as ``instance.variable``."""
        return f"{self.target}.{self.target_var}"


@dataclass(frozen=True)
class Action:
    """Values set at an exact time.

    Attributes
    ----------
    time : Fraction
        When (s); must be a communication point of the base grid.
    values : mapping of (instance, variable) to value
    """

    time: Fraction
    values: MappingProxyType


@dataclass(frozen=True)
class Scenario:
    """A complete co-simulation scenario.

    Attributes
    ----------
    experiment : Experiment
    instances : tuple of Instance
    connections : tuple of Connection
    actions : tuple of Action, sorted by time
    record : tuple of str
        Recorded variables as ``instance.variable``.
    base_dir : Path or None
        Folder used to resolve relative FMU names (the scenario file's folder).
    source : str
        Where the scenario came from (file name or ``"<dict>"``), for messages.
    """

    experiment: Experiment
    instances: tuple
    connections: tuple = ()
    actions: tuple = ()
    record: tuple = ()
    base_dir: Path | None = None
    source: str = "<dict>"

    def instance(self, name: str) -> Instance:
        """Return the instance called `name`, or raise ScenarioError with suggestions."""
        for inst in self.instances:
            if inst.name == name:
                return inst
        names = [i.name for i in self.instances]
        raise ScenarioError(f"scenario has no instance {name!r}{closest(name, names)}")

    def with_overrides(self, overrides) -> Scenario:
        """Return a copy with parameter overrides applied.

        Parameters
        ----------
        overrides : mapping of str to value, or iterable of "inst.var=value" strings
            Each key ``inst.var`` sets a start value of instance ``inst``.
        """
        if not overrides:
            return self
        if isinstance(overrides, dict) or hasattr(overrides, "items"):
            items = list(overrides.items())
        else:
            items = [parse_override(s) for s in overrides]
        params = {i.name: dict(i.parameters) for i in self.instances}
        for key, value in items:
            inst, var = _split_ref(key, "override")
            if inst not in params:
                raise ScenarioError(
                    f"override {key!r} names no instance of the scenario{closest(inst, params)}"
                )
            params[inst][var] = value
        new = tuple(replace(i, parameters=_freeze(params[i.name])) for i in self.instances)
        return replace(self, instances=new)

    def with_periods(self, periods) -> Scenario:
        """Return a copy with some instances' communication periods replaced.

        Parameters
        ----------
        periods : mapping of str to float, str or Fraction
            Instance name to its new period (s), positive.
        """
        if not periods:
            return self
        names = {i.name for i in self.instances}
        new = {}
        for name, value in periods.items():
            if name not in names:
                raise ScenarioError(f"period given for {name!r}, which is no instance of the "
                                    f"scenario{closest(name, names)}")
            new[name] = _time(value, f"period of {name}")
            if not new[name] > 0:
                raise ScenarioError(f"period of {name} is {value!r}; expected a positive "
                                    "time in seconds")
        return replace(self, instances=tuple(
            replace(i, period=new.get(i.name, i.period)) for i in self.instances))

    def with_experiment(self, **changes) -> Scenario:
        """Return a copy with experiment fields replaced (stop, algorithm, ...)."""
        exp = self.experiment
        for key in ("stop", "output_interval", "start"):
            if changes.get(key) is not None:
                changes[key] = _time(changes[key], f"experiment.{key}")
        changes = {k: v for k, v in changes.items() if v is not None}
        if "algorithm" in changes:
            changes["algorithm"] = _algorithm(changes["algorithm"])
        if "fmu_kind" in changes:
            changes["fmu_kind"] = _fmu_kind(changes["fmu_kind"])
        new = replace(exp, **changes)
        _check_experiment(new)
        return replace(self, experiment=new)

    def to_dict(self) -> dict:
        """Return the scenario as plain TOML-compatible data (exact times as strings)."""
        exp = self.experiment
        d = {
            "experiment": {
                "start": _fstr(exp.start),
                "stop": _fstr(exp.stop),
                "output_interval": _fstr(exp.output_interval),
                "algorithm": exp.algorithm,
                **({} if exp.fmu_kind == "native" else {"fmu_kind": exp.fmu_kind}),
            },
            "fmus": {
                i.name: {"fmu": i.fmu, "period": _fstr(i.period), "parameters": dict(i.parameters)}
                for i in self.instances
            },
            "connections": [
                {"from": c.start, "to": c.end, "gain": c.gain, "offset": c.offset}
                for c in self.connections
            ],
            "actions": [
                {"time": _fstr(a.time), "set": {f"{k[0]}.{k[1]}": v for k, v in a.values.items()}}
                for a in self.actions
            ],
            "record": {"variables": list(self.record)},
        }
        return d

    def digest(self) -> str:
        """Return the SHA-256 of the scenario's canonical JSON form."""
        text = json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()


def _fstr(x: Fraction) -> str:
    """Exact decimal string when there is one, else 'num/den'."""
    d = x.denominator
    while d % 2 == 0:
        d //= 2
    while d % 5 == 0:
        d //= 5
    if d != 1:
        return f"{x.numerator}/{x.denominator}"
    f = float(x)
    if Fraction(repr(f)) == x:
        return repr(f)
    return f"{x.numerator}/{x.denominator}"


def _time(value, what: str) -> Fraction:
    try:
        return to_fraction(value, what)
    except TimebaseError as exc:
        raise ScenarioError(str(exc)) from None


def _algorithm(value) -> str:
    alg = str(value).strip().lower().replace("_", "-")
    if alg == "gaussseidel":
        alg = "gauss-seidel"
    if alg not in ALGORITHMS:
        raise ScenarioError(
            f"algorithm {value!r} is unknown; expected one of {', '.join(ALGORITHMS)}"
            f"{closest(alg, ALGORITHMS)}"
        )
    return alg


def _fmu_kind(value) -> str:
    kind = str(value).strip().lower()
    if kind not in FMU_KINDS:
        raise ScenarioError(f"fmu_kind {value!r} is unknown; expected one of "
                            f"{', '.join(FMU_KINDS)}{closest(kind, FMU_KINDS)}")
    return kind


def _check_experiment(exp: Experiment) -> None:
    if exp.output_interval <= 0:
        raise ScenarioError(
            f"experiment.output_interval is {float(exp.output_interval)!r} s; expected > 0"
        )
    if exp.stop <= exp.start:
        raise ScenarioError(
            f"experiment.stop ({float(exp.stop)!r} s) is not after experiment.start "
            f"({float(exp.start)!r} s)"
        )


def _split_ref(ref, what: str) -> tuple:
    if not isinstance(ref, str) or "." not in ref:
        raise ScenarioError(f"{what} {ref!r} must have the form 'instance.variable'")
    inst, var = ref.split(".", 1)
    if not inst or not var:
        raise ScenarioError(f"{what} {ref!r} must have the form 'instance.variable'")
    return inst, var


def _expect_table(value, what: str) -> dict:
    if not isinstance(value, dict):
        raise ScenarioError(f"{what} must be a table; got {type(value).__name__} "
                            f"{short_repr(value)}")
    return value


def check_keys(table, allowed, what: str, error: type[Exception] = ScenarioError) -> None:
    """Raise ``error`` naming the first key of ``table`` not in ``allowed``.

    Parameters
    ----------
    table : mapping
        A table read from a scenario or campaign file.
    allowed : iterable of str
        Its valid keys.
    what : str
        How the message names the table, e.g. ``"[experiment]"``.
    error : exception class
        Raised with one sentence: the key, the closest valid keys, all valid keys.
    """
    allowed = tuple(allowed)
    for key in table:
        if key not in allowed:
            raise error(f"{what} has an unknown key {key!r}{closest(key, allowed)}; expected "
                        f"one of {', '.join(allowed)}")


def parse_override(text: str) -> tuple:
    """Parse ``inst.var=value`` into ``("inst.var", value)``.

    The value is read as a TOML value (``1e-3``, ``true``, ``"text"``); anything that is
    not valid TOML is taken as a plain string.
    """
    if "=" not in text:
        raise ScenarioError(f"override {text!r} must have the form 'instance.variable=value'")
    key, raw = text.split("=", 1)
    key, raw = key.strip(), raw.strip()
    _split_ref(key, "override")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return key, value
