"""A scenario checked against its FMUs' model descriptions: the plan a simulation runs."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from fractions import Fraction
from math import gcd

from ..scenario import Scenario, ScenarioError, closest
from ..timebase import Timebase, make_timebase
from .errors import JacobiLoopWarning, TimebaseWarning, UnconnectedInputWarning
from .fmuinfo import FmuInfo, Variable, find_fmu, read_fmu_info
from .graph import AlgebraicLoopError, feedthrough_edges, step_groups

__all__ = ["Plan", "prepare", "coerce"]


@dataclass(frozen=True)
class Plan:
    """A checked scenario, ready to run.

    Attributes
    ----------
    scenario : Scenario
    fmus : dict of str to FmuInfo
        Per instance.
    timebase : Timebase
    groups : list of tuple of str
        Step order (Gauss–Seidel); tuples of several instances are algebraic loops.
    loops : list of Loop
    feedthrough_edges : list of Connection
    unconnected : list of str
        Inputs nothing drives (``instance.variable``).
    """

    scenario: Scenario
    fmus: dict
    timebase: Timebase
    groups: list
    loops: list
    feedthrough_edges: list
    unconnected: list


def _var(info: FmuInfo, inst: str, var: str, what: str) -> Variable:
    try:
        return info.variables[var]
    except KeyError:
        raise ScenarioError(
            f"{what} refers to unknown variable {inst}.{var} (FMU {info.path.name})"
            f"{closest(var, info.variables)}"
        ) from None


_SETTABLE_START = {"parameter", "input"}


def _short(value, limit: int = 60) -> str:
    """``repr(value)`` cut to about ``limit`` characters for an error line."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit - 20]}...{text[-12:]} " \
        f"({len(text)} characters)"


def coerce(value, v: Variable, ref: str):
    """Check a start/action value against the variable type and return it typed.

    Parameters
    ----------
    value : object
        The value from the scenario, in the variable's unit.
    v : Variable
        The FMU variable; its FMI type decides the check.
    ref : str
        ``"instance.variable"`` reference for error messages.

    Returns
    -------
    float, int, bool or str
        The value as the variable's type (Real, Integer/Enumeration, Boolean, String).
    """
    t = v.type
    got = f"got {type(value).__name__} {_short(value)}"
    if t == "Real":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ScenarioError(f"{ref} is Real; {got}")
        try:
            x = float(value)
        except OverflowError:
            x = math.inf
        if not math.isfinite(x):
            raise ScenarioError(f"{ref} is Real; got {_short(value)}, expected a finite number")
        return x
    if t in ("Integer", "Enumeration"):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ScenarioError(f"{ref} is {t}; {got}")
        if not -2**31 <= value < 2**31:
            raise ScenarioError(f"{ref} is {t}; got {_short(value)}, outside the 32-bit range "
                                "of an FMI 2.0 Integer")
        return int(value)
    if t == "Boolean":
        if not isinstance(value, bool):
            raise ScenarioError(f"{ref} is Boolean; {got}")
        return value
    if t == "String":
        if not isinstance(value, str):
            raise ScenarioError(f"{ref} is String; {got}")
        return value
    raise ScenarioError(f"{ref} has unsupported type {t}")


def _warn_slow_timebase(scenario: Scenario, fmus: dict, tb: Timebase) -> None:
    """Warn when the output interval or a period makes the run far slower than needed."""
    ticks = list(tb.period_ticks.values())
    common = 0
    for t in ticks:
        common = gcd(common, t)
    if common > 1:   # the output interval alone refines the grid
        step = float(tb.base * common)
        warnings.warn(TimebaseWarning(
            f"output interval {float(scenario.experiment.output_interval)!r} s is not a "
            f"multiple of the instances' common step {step!r} s, so the base step becomes "
            f"{float(tb.base)!r} s and the run steps through {common} times as many ticks; "
            "choose an output interval that is a multiple of it"), stacklevel=3)
    for inst in scenario.instances:
        de = getattr(fmus[inst.name].model_description, "defaultExperiment", None)
        hint = getattr(de, "stepSize", None) if de is not None else None
        try:
            hint = float(hint) if hint is not None else None
        except (TypeError, ValueError):
            hint = None
        if hint and Fraction(inst.period) * 100 < Fraction(hint):
            n = tb.n_ticks // tb.period_ticks[inst.name]
            warnings.warn(TimebaseWarning(
                f"instance {inst.name!r} steps every {float(inst.period)!r} s, "
                f"{hint / float(inst.period):.0f} times finer than its FMU's default step "
                f"({hint!r} s): {n} steps; check the period"), stacklevel=3)


def _refuse_empty_rates(scenario: Scenario) -> None:
    """A period or output interval longer than the run: nothing would step or record."""
    exp = scenario.experiment
    length = float(exp.stop) - float(exp.start)
    for inst in scenario.instances:
        if float(inst.period) > length:
            raise ScenarioError(
                f"instance {inst.name!r} has period {float(inst.period)!r} s, longer than the "
                f"run ({length!r} s): it would never step; give it a period of at most the "
                "run's length")
    if exp.output_interval is not None and float(exp.output_interval) > length:
        raise ScenarioError(
            f"experiment.output_interval {float(exp.output_interval)!r} s is longer than the "
            f"run ({length!r} s): it would record one row; choose an interval of at most "
            "the run's length")


def prepare(scenario: Scenario, fmu_dir=None) -> Plan:
    """Check a scenario against its FMUs' model descriptions; instantiate nothing.

    Raises ScenarioError (unknown FMU, instance or variable; incompatible connection;
    input driven twice; bad times), TimebaseError, or AlgebraicLoopError (an unsolvable
    loop under Gauss–Seidel).  Warns with UnconnectedInputWarning.

    Parameters
    ----------
    scenario : Scenario
    fmu_dir : path-like, optional
        Extra folder searched first for FMU names.

    Returns
    -------
    Plan
    """
    fmus = {i.name: read_fmu_info(find_fmu(i.fmu, scenario, fmu_dir)) for i in scenario.instances}
    driven = {}
    for c in scenario.connections:
        what = f"connection {c.start} -> {c.end}"
        src = _var(fmus[c.source], c.source, c.source_var, what)
        dst = _var(fmus[c.target], c.target, c.target_var, what)
        if src.causality != "output":
            raise ScenarioError(f"{what}: source {c.start} is a {src.causality}; expected an "
                                "output")
        if dst.causality != "input":
            raise ScenarioError(f"{what}: target {c.end} is a {dst.causality}, not an input")
        if src.type != dst.type:
            raise ScenarioError(f"{what} joins a {src.type} to a {dst.type}; types must match")
        if src.type not in ("Real", "Integer", "Boolean"):
            raise ScenarioError(f"{what} carries a {src.type}; only Real, Integer and "
                                "Boolean signals can be connected")
        if (c.gain != 1.0 or c.offset != 0.0) and src.type != "Real":
            raise ScenarioError(f"{what} has a gain or offset but carries a {src.type}; "
                                "only Real signals can be scaled")
        if src.unit and dst.unit and src.unit != dst.unit:
            raise ScenarioError(f"{what} joins unit {src.unit!r} to unit {dst.unit!r}; "
                                "units must match")
        if c.end in driven:
            raise ScenarioError(f"input {c.end} is driven twice (from {driven[c.end]} and "
                                f"{c.start}); an input takes one connection")
        driven[c.end] = c.start
    for inst in scenario.instances:
        for name, value in inst.parameters.items():
            ref = f"start value {inst.name}.{name}"
            v = _var(fmus[inst.name], inst.name, name, ref)
            if v.causality not in _SETTABLE_START or v.variability == "constant":
                raise ScenarioError(f"{ref}: {inst.name}.{name} is a {v.variability} "
                                    f"{v.causality}; only parameters and inputs can be set")
            coerce(value, v, f"{inst.name}.{name}")
    for ref in scenario.record:
        inst, var = ref.split(".", 1)
        v = _var(fmus[inst], inst, var, f"recorded variable {ref}")
        if v.type not in ("Real", "Integer", "Boolean", "Enumeration"):
            raise ScenarioError(f"recorded variable {ref} is a {v.type}; only numbers and "
                                "booleans can be recorded")
    exp = scenario.experiment
    _refuse_empty_rates(scenario)
    tb = make_timebase({i.name: i.period for i in scenario.instances}, exp.output_interval,
                       exp.stop, exp.start)
    _warn_slow_timebase(scenario, fmus, tb)
    acted = set()
    for a in scenario.actions:
        if not exp.start <= a.time <= exp.stop:
            raise ScenarioError(f"action at {float(a.time)!r} s is outside the run "
                                f"[{float(exp.start)!r}, {float(exp.stop)!r}] s")
        tb.ticks_of(a.time, "action time")
        for (inst, var), value in a.values.items():
            ref = f"{inst}.{var}"
            v = _var(fmus[inst], inst, var, f"action at {float(a.time)!r} s")
            tunable = v.causality == "parameter" and v.variability == "tunable"
            if not (v.causality == "input" or tunable):
                raise ScenarioError(f"action at {float(a.time)!r} s sets {ref}, a "
                                    f"{v.variability} {v.causality}; only inputs and tunable "
                                    "parameters can change during a run")
            if ref in driven:
                raise ScenarioError(f"input {ref} is driven twice (by connection from "
                                    f"{driven[ref]} and by an action)")
            coerce(value, v, ref)
            acted.add(ref)
    ft = {i.name: fmus[i.name].feedthrough for i in scenario.instances}
    edges = feedthrough_edges(scenario.connections, ft)
    names = [i.name for i in scenario.instances]
    groups, loops = step_groups(names, edges)
    if exp.algorithm == "gauss-seidel":
        for loop in loops:
            bad = [m for m in loop.members if not fmus[m].can_get_set_state]
            if bad:
                raise AlgebraicLoopError(
                    f"algebraic loop {loop.describe()} cannot be solved because "
                    f"{', '.join(bad)} cannot get and set its FMU state; break the loop "
                    "(an output without direct feedthrough, e.g. a unit delay) or run "
                    "with algorithm 'jacobi'"
                )
    else:
        for loop in loops:
            warnings.warn(JacobiLoopWarning(
                f"algebraic loop {loop.describe()} is not solved under algorithm 'jacobi': "
                "each pass around it reads the previous step's values, so a loop gain above "
                "1 diverges; run with 'gauss-seidel' to solve it at every step"), stacklevel=2)
    unconnected = []
    for inst in scenario.instances:
        given = set(inst.parameters)
        for n, v in fmus[inst.name].variables.items():
            ref = f"{inst.name}.{n}"
            if v.causality == "input" and ref not in driven and n not in given \
                    and ref not in acted:
                unconnected.append(ref)
    if unconnected:
        warnings.warn(
            f"{len(unconnected)} input(s) are not connected and keep their start values: "
            + ", ".join(unconnected), UnconnectedInputWarning, stacklevel=2)
    return Plan(scenario, fmus, tb, groups, loops, edges, unconnected)
