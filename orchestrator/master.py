"""The multi-rate co-simulation master for FMI 2.0 co-simulation FMUs (through fmpy).

Semantics
---------
Time is an integer tick on an exact rational base step (:mod:`orchestrator.timebase`).
An instance with period ``p`` ticks steps at every tick ``k`` with ``k % p == 0`` from
``t_k`` to ``t_k + p·base``; its inputs are set just before and held over the step
(zero-order hold).  A connection carries ``gain * output + offset``.

After a step from ``t_k`` to ``t_k + h`` an output is the value at ``t_k + h``; it is
*stamped* ``t_k + h`` and becomes the source's value at communication points from then
on.  The one exception is an output with direct feedthrough (ModelStructure
``dependencies`` on a connected input): it is computed from the inputs of the step at
``t_k`` and is used at once, as a discrete controller's output ``u_k = C x_k + D y_k``
is applied over its own sample interval.  At a tick, every due instance reads its
connected inputs and steps:

* ``gauss-seidel`` (default): a feedthrough output is read after its source stepped in
  this tick (sources before sinks, topological order of the feedthrough graph); any
  other output is read at its value at ``t_k`` (the latest value stamped ``<= t_k``),
  so independent instances never depend on the order they step in, and a slow
  source's output is never seen before its time.  A cycle of feedthrough is an
  algebraic loop: it is iterated to a fixed point, rolling the members back with
  ``fmi2SetFMUstate`` between iterations, when every member can get and set its state.
* ``jacobi``: every input reads its source's value at ``t_k`` (stamped ``<= t_k``).
  For periods that divide one another this is exactly libcosim's fixed-step algorithm
  (libcosim exchanges values only at common multiples of the two periods, so it
  differs when neither period divides the other).

Recorded rows are the values at ticks that are multiples of the output interval: each
variable's value at ``t_k`` (the latest stamped ``<= t_k``), read before that tick's steps.
"""

from __future__ import annotations

import ctypes
import gc
import itertools
import math
import os
import shutil
import signal
import threading
import time as _time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .graph import AlgebraicLoopError, feedthrough_edges, init_order, step_groups
from .scenario import Scenario, ScenarioError, closest
from .timebase import Timebase, make_timebase
from .files import atomic_write, sha256_file

__all__ = [
    "SimulationError",
    "OutputError",
    "PARTIAL_DIR",
    "UnconnectedInputWarning",
    "TimebaseWarning",
    "JacobiLoopWarning",
    "EarlyEndWarning",
    "FmuInfo",
    "Variable",
    "Plan",
    "find_fmu",
    "read_fmu_info",
    "prepare",
    "Simulation",
    "run_scenario",
]

#: Largest hyperperiod for which the due pattern is precomputed (ticks).
_MAX_PATTERN = 200_000
_STATUS = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"]


class SimulationError(RuntimeError):
    """An FMU failed, raised, or produced a non-finite value during a run.

    Attributes
    ----------
    instance : str or None
    time : float or None
        Communication point of the failing step (s).
    result : RunResult or None
        What was recorded up to the failure (set by :func:`orchestrator.run_scenario`).
    """

    def __init__(self, message, instance=None, time=None):
        super().__init__(message)
        self.instance = instance
        self.time = time
        self.result = None


class _TerminationRequested(Exception):
    """An FMU's fmi2DoStep returned Discard with fmi2Terminated true (a normal end)."""

    def __init__(self, instance, time, message=""):
        super().__init__(instance, time, message)
        self.instance = instance
        self.time = time
        self.message = message


class EarlyEndWarning(UserWarning):
    """An FMU ended the run before the stop time by asking to terminate (not an error)."""


class TimebaseWarning(UserWarning):
    """A run whose tick grid is much finer than its instances need."""


class JacobiLoopWarning(UserWarning):
    """An algebraic loop that the Jacobi algorithm leaves unsolved (one step late)."""


class UnconnectedInputWarning(UserWarning):
    """Inputs that no connection, parameter or action drives."""


@dataclass(frozen=True)
class Variable:
    """One scalar variable of an FMU's model description."""

    name: str
    vr: int
    type: str
    causality: str
    variability: str
    unit: str | None
    start: object = None


@dataclass(frozen=True)
class FmuInfo:
    """What the master needs from an FMU without instantiating it.

    Attributes
    ----------
    path : Path
    sha256 : str
    model_identifier, guid : str
    variables : dict of str to Variable
    feedthrough : dict of str to frozenset of str
        Each output's direct input dependencies.
    can_get_set_state : bool
    """

    path: Path
    sha256: str
    model_identifier: str
    guid: str
    variables: dict
    feedthrough: dict
    can_get_set_state: bool
    model_description: object = field(repr=False, compare=False, default=None)


_INFO_CACHE: dict = {}
#: FMU objects whose shared libraries stay loaded for the life of the process.
_KEEP_LOADED: list = []


def read_fmu_info(path) -> FmuInfo:
    """Read an FMU's model description and dependency structure (cached per file).

    Parameters
    ----------
    path : path-like
        The ``.fmu`` file.

    Returns
    -------
    FmuInfo
    """
    from fmpy import read_model_description

    path = Path(path).resolve()
    st = path.stat()
    key = (str(path), st.st_mtime_ns, st.st_size)
    if key in _INFO_CACHE:
        return _INFO_CACHE[key]
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:
        raise ScenarioError(f"FMU {str(path)!r} has no readable modelDescription.xml: {exc}")
    if md.fmiVersion != "2.0" or md.coSimulation is None:
        raise ScenarioError(
            f"FMU {str(path)!r} is FMI {md.fmiVersion} "
            f"{'co-simulation' if md.coSimulation else 'model exchange only'}; "
            "expected FMI 2.0 co-simulation"
        )
    variables = {}
    for v in md.modelVariables:
        unit = v.unit or (v.declaredType.unit if v.declaredType is not None else None)
        variables[v.name] = Variable(v.name, int(v.valueReference), v.type, v.causality,
                                     v.variability, unit, v.start)
    inputs = frozenset(n for n, v in variables.items() if v.causality == "input")
    feedthrough = {}
    for u in md.outputs:
        if u.dependencies is None:  # FMI 2.0: no attribute means "depends on all inputs"
            feedthrough[u.variable.name] = inputs
        else:
            feedthrough[u.variable.name] = frozenset(
                d.name for d in u.dependencies if d.name in inputs)
    for n, v in variables.items():
        if v.causality == "output" and n not in feedthrough:
            feedthrough[n] = inputs
    info = FmuInfo(path, sha256_file(path), md.coSimulation.modelIdentifier, md.guid,
                   variables, feedthrough, bool(md.coSimulation.canGetAndSetFMUstate), md)
    _INFO_CACHE[key] = info
    return info


def _search_dirs(scenario: Scenario, fmu_dir=None) -> list:
    dirs = []
    if fmu_dir is not None:
        dirs.append(Path(fmu_dir))
    if scenario.base_dir is not None:
        base = Path(scenario.base_dir)
        dirs += [base / "fmus", base, base.parent / "fmus"]
    dirs += [Path.cwd() / "fmus", Path.cwd()]
    seen, out = set(), []
    for d in dirs:
        r = d.resolve()
        if r not in seen:
            seen.add(r)
            out.append(d)
    return out


def find_fmu(name: str, scenario: Scenario, fmu_dir=None) -> Path:
    """Resolve an FMU name or path of a scenario to an existing ``.fmu`` file.

    A bare name ``x`` is looked up as ``x.fmu`` in `fmu_dir`, then in ``fmus/`` next to
    the scenario file, next to it, in ``fmus/`` of its parent folder, and in ``fmus/`` of
    the current folder.  A name with a suffix or a folder is a path (relative to the
    scenario folder, then the current folder).
    """
    p = Path(name)
    if p.suffix.lower() == ".fmu" or len(p.parts) > 1:
        for cand in ([p] if p.is_absolute() else
                     [(scenario.base_dir or Path.cwd()) / p, Path.cwd() / p]):
            if cand.is_file():
                return cand
        raise ScenarioError(f"FMU file {name!r} does not exist")
    dirs = _search_dirs(scenario, fmu_dir)
    for d in dirs:
        cand = d / f"{name}.fmu"
        if cand.is_file():
            return cand
    known = sorted({f.stem for d in dirs if d.is_dir() for f in d.glob("*.fmu")})
    where = ", ".join(str(d) for d in dirs)
    raise ScenarioError(
        f"unknown FMU {name!r}: no {name}.fmu in {where}{closest(name, known)}"
        + ("" if known else "; build the FMUs first (jitterfmu build) or pass --fmu-dir")
    )


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


def _coerce(value, v: Variable, ref: str):
    """Check a start/action value against the variable type and return it typed."""
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
    from fractions import Fraction
    from math import gcd

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
            _coerce(value, v, f"{inst.name}.{name}")
    for ref in scenario.record:
        inst, var = ref.split(".", 1)
        v = _var(fmus[inst], inst, var, f"recorded variable {ref}")
        if v.type not in ("Real", "Integer", "Boolean", "Enumeration"):
            raise ScenarioError(f"recorded variable {ref} is a {v.type}; only numbers and "
                                "booleans can be recorded")
    exp = scenario.experiment
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
            _coerce(value, v, ref)
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


# ---------------------------------------------------------------------------------------
# Running


_LOG_KEYS = itertools.count(1)
_LOG_SINKS: dict[int, list] = {}
_LOG_BY_NAME: dict[str, list] = {}  # the latest instance of each name
_LOGGER = []


def _shared_logger(logger_type):
    """The one FMI logger callback of the process (created once, never freed)."""
    if not _LOGGER:
        def log(env, inst, status, category, message):
            sink = _LOG_SINKS.get(env or 0)
            if sink is None:  # an FMU that does not hand back its componentEnvironment
                sink = _LOG_BY_NAME.get(inst.decode("utf-8", "replace") if inst else "")
            if sink is None:
                return
            text = message.decode("utf-8", "replace") if message else ""
            sink.append((status, text))
            del sink[:-20]

        _LOGGER.append(logger_type(log))
    return _LOGGER[0]


class _Slave:
    """One instantiated FMU with raw FMI function handles and precomputed arrays."""

    def __init__(self, name, info, unzipdir, instance_spec, timebase):
        from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
        import fmpy.fmi2 as f2

        self.name = name
        self.info = info
        self.messages = []
        self.period_ticks = timebase.period_ticks[name]
        p = instance_spec.period * 1  # Fraction
        self.h = p.numerator / p.denominator
        self.fmu = FMU2Slave(guid=info.guid, unzipDirectory=unzipdir,
                             modelIdentifier=info.model_identifier, instanceName=name)

        # fmpy's variadic-formatting proxy keeps one logger per process, so every
        # instance logs through one callback that finds the instance's message list by
        # the componentEnvironment the FMU hands back
        self._log_key = next(_LOG_KEYS)
        _LOG_SINKS[self._log_key] = _LOG_BY_NAME[name] = self.messages
        cb = fmi2CallbackFunctions()
        cb.logger = _shared_logger(fmi2CallbackLoggerTYPE)
        cb.allocateMemory = f2.defaultCallbacks.allocateMemory
        cb.freeMemory = f2.defaultCallbacks.freeMemory
        cb.componentEnvironment = ctypes.c_void_p(self._log_key)
        try:
            from fmpy.logging import addLoggerProxy

            addLoggerProxy(ctypes.byref(cb))
        except Exception:  # pragma: no cover - formatting proxy is optional
            pass
        self._log = None  # the shared logger lives in _LOGGER
        self._cb = cb
        self.instantiated = False
        self.fatal = False
        self.fmu.instantiate(callbacks=cb, loggingOn=True)
        self.instantiated = True
        self.comp = self.fmu.component
        fn = self.fmu._functions
        self.getReal = fn["fmi2GetReal"]
        self.setReal = fn["fmi2SetReal"]
        self.getInteger = fn["fmi2GetInteger"]
        self.setInteger = fn["fmi2SetInteger"]
        self.getBoolean = fn["fmi2GetBoolean"]
        self.setBoolean = fn["fmi2SetBoolean"]
        self.doStep = fn["fmi2DoStep"]
        self._getBooleanStatus = fn["fmi2GetBooleanStatus"]

    def asks_to_terminate(self) -> bool:
        """True if ``fmi2GetBooleanStatus(fmi2Terminated)`` answers fmi2OK and true.

        FMI 2.0 (4.2.3): after fmi2DoStep returned fmi2Discard, a slave that wants the
        simulation to end reports fmi2Terminated = true; any other answer (including
        an error from a slave that does not support the inquiry) means a failed step.
        """
        from fmpy.fmi2 import fmi2Terminated

        value = ctypes.c_int(0)
        try:
            st = self._getBooleanStatus(self.comp, fmi2Terminated, ctypes.byref(value))
        except Exception:
            return False
        return st == 0 and bool(value.value)

    def last_message(self) -> str:
        bad = [m for s, m in self.messages if s >= 1 and m]
        return bad[-1] if bad else (self.messages[-1][1] if self.messages else "")

    def set_values(self, values):
        """Set typed values given as [(Variable, value)] (slow path, not per step)."""
        for v, value in values:
            vr = [v.vr]
            if v.type == "Real":
                self.fmu.setReal(vr, [float(value)])
            elif v.type in ("Integer", "Enumeration"):
                self.fmu.setInteger(vr, [int(value)])
            elif v.type == "Boolean":
                self.fmu.setBoolean(vr, [bool(value)])
            else:
                self.fmu.setString(vr, [str(value)])

    def close(self):
        if self.instantiated and self.fatal:
            _KEEP_LOADED.append((self.fmu, self._cb, self._log))
            self.instantiated = False
        if self.instantiated:
            try:
                self.fmu.terminate()
            except Exception:
                pass
            try:
                # free the instance but keep the shared library loaded: a pythonfmu FMU
                # leaves Python objects behind whose code lives in that library, and
                # unloading it makes a later garbage collection crash the process
                self.fmu.fmi2FreeInstance(self.comp)
            except Exception:
                pass
            # keep the callbacks alive for the slave's leftovers collected later
            _KEEP_LOADED.append((self.fmu, self._cb, self._log))
            self.instantiated = False


class Simulation:
    """Instantiate, initialise and step a prepared scenario.

    Parameters
    ----------
    plan : Plan
        From :func:`prepare`.
    max_iterations : int
        Fixed-point iterations allowed per algebraic-loop solve.
    loop_tolerance : float
        Convergence test ``|x_new - x_old| <= tol * (1 + |x_new|)`` on loop signals.

    Examples
    --------
    >>> sim = Simulation(prepare(scenario))  # doctest: +SKIP
    >>> try:
    ...     sim.initialize(); sim.run()
    ... finally:
    ...     sim.close()
    >>> table = sim.table()
    """

    def __init__(self, plan: Plan, max_iterations: int = 100, loop_tolerance: float = 1e-12):
        self.plan = plan
        self.max_iterations = max_iterations
        self.loop_tolerance = loop_tolerance
        self.slaves = {}
        self.rows = 0
        self.tick = 0
        #: ``(instance, time, message)`` when an FMU ended the run early (fmi2Terminated)
        self.terminated = None
        self._build_bus()

    # -- layout --------------------------------------------------------------------

    def _build_bus(self):
        plan, sc = self.plan, self.plan.scenario
        algorithm = sc.experiment.algorithm
        # bus layout: per instance the Real outputs + any recorded Real, then Integer, Boolean
        self.slot = {}
        self.reads = {}
        n = 0
        for inst in sc.instances:
            info = plan.fmus[inst.name]
            wanted = {"Real": [], "Integer": [], "Boolean": []}
            for vname, v in info.variables.items():
                if v.causality == "output" and v.type in wanted:
                    wanted[v.type].append(v)
            for ref in sc.record:
                i, var = ref.split(".", 1)
                if i == inst.name:
                    v = info.variables[var]
                    t = "Integer" if v.type == "Enumeration" else v.type
                    if v not in wanted[t]:
                        wanted[t].append(v)
            reads = {}
            for t, vs in wanted.items():
                reads[t] = (n, vs)
                for v in vs:
                    self.slot[(inst.name, v.name)] = n
                    n += 1
            self.reads[inst.name] = reads
        self.n_bus = n
        # big[:n] is the snapshot at the start of the tick, big[n:2n] the latest values,
        # big[2n:] the outputs of feedthrough sources read at t_k after their inputs
        # were set and before they step (FMI: the outputs at t_k for the inputs at t_k)
        self.big = np.zeros(3 * max(n, 1))
        # inputs: per instance, gather indices into big and scale
        in_loop = {m for g in plan.groups if len(g) > 1 for m in g}
        in_loop |= {l.members[0] for l in plan.loops}
        ft = {(c.source, c.source_var, c.target, c.target_var) for c in plan.feedthrough_edges}
        gs = algorithm == "gauss-seidel"
        # sources of feedthrough edges outside algebraic loops: read before stepping
        self.ft_sources = {c.source for c in plan.feedthrough_edges
                           if gs and c.source not in in_loop}
        self.inputs = {}
        for inst in sc.instances:
            by_type = {"Real": [], "Integer": [], "Boolean": []}
            for c in sc.connections:
                if c.target != inst.name:
                    continue
                v = plan.fmus[inst.name].variables[c.target_var]
                src = self.slot[(c.source, c.source_var)]
                latest = gs and (c.source, c.source_var, c.target, c.target_var) in ft
                if latest and c.source in self.ft_sources:
                    idx = src + 2 * n      # value at t_k, read before the source steps
                elif latest:
                    idx = src + n          # inside an algebraic loop: iterated values
                else:
                    idx = src              # value stamped <= t_k
                by_type[v.type].append((v, idx, c.gain, c.offset))
            self.inputs[inst.name] = by_type
        rec_idx = []
        for r in sc.record:
            inst, var = r.split(".", 1)
            i = self.slot[(inst, var)]
            if inst in self.ft_sources and plan.fmus[inst].feedthrough.get(var):
                i += 2 * n  # a feedthrough output's value at t_k is the one read before stepping
            rec_idx.append(i)
        self.record_idx = np.array(rec_idx, dtype=np.intp)
        tb = plan.timebase
        self.n_rows = tb.n_ticks // tb.output_ticks + 1
        self.rec = np.full((self.n_rows, len(sc.record)), np.nan)
        self.times = np.array(
            [tb.time(r * tb.output_ticks) for r in range(self.n_rows)], dtype=float)

    # -- lifecycle -----------------------------------------------------------------

    def _fail(self, slave, what, t, status=None, exc=None):
        msg = f"instance {slave.name!r} failed in {what} at t = {t!r} s"
        if status is None and isinstance(getattr(exc, "status", None), int):
            status = exc.status  # fmpy's FMICallException carries the FMI status
        if status == 4 or any(st == 4 for st, _ in slave.messages):
            slave.fatal = True  # FMI 2.0: after fmi2Fatal no further call is allowed
        if status is not None:
            msg += f" with status {_STATUS[status] if status < len(_STATUS) else status}"
        detail = slave.last_message() or (str(exc) if exc else "")
        if detail:
            msg += ": " + " ".join(detail.split())
        return SimulationError(msg, slave.name, t)

    def _load(self):
        plan, sc = self.plan, self.plan.scenario
        unzipped = {}
        for inst in sc.instances:
            info = plan.fmus[inst.name]
            key = str(info.path)
            if key not in unzipped:
                unzipped[key] = _extracted(info)
            try:
                self.slaves[inst.name] = _Slave(inst.name, info, unzipped[key], inst, plan.timebase)
            except Exception as exc:
                raise SimulationError(
                    f"instance {inst.name!r} could not be loaded from {info.path.name}: {exc}",
                    inst.name, float(sc.experiment.start)) from exc

    def initialize(self):
        """Instantiate every FMU, set start values and initialise in dependency order."""
        plan, sc = self.plan, self.plan.scenario
        self._load()
        t0 = float(sc.experiment.start)
        t1 = float(sc.experiment.stop)
        order = init_order([i.name for i in sc.instances], sc.connections,
                           {i.name: plan.fmus[i.name].feedthrough for i in sc.instances})
        for inst in sc.instances:
            s = self.slaves[inst.name]
            info = plan.fmus[inst.name]
            try:
                s.fmu.setupExperiment(startTime=t0, stopTime=t1)
                s.set_values([(info.variables[k], v) for k, v in inst.parameters.items()])
                s.fmu.enterInitializationMode()
            except Exception as exc:
                raise self._fail(s, "initialisation", t0, exc=exc) from exc
        self._compile()
        n = self.n_bus
        for name in order:  # sources first: a sink's inputs see initialised outputs
            s = self.slaves[name]
            try:
                self._read_all(order)
                self.big[:n] = self.big[n:2 * n]
                self._push_inputs(name)
                s.fmu.exitInitializationMode()
            except SimulationError:
                raise
            except Exception as exc:
                raise self._fail(s, "initialisation", t0, exc=exc) from exc
        self._read_all(order)
        self.big[:n] = self.big[n:2 * n]
        for name in order:
            self._push_inputs(name)
        self._check_finite(t0, order, "initialisation")

    def _read_all(self, order):
        for name in order:
            self._read(name)

    def _read(self, name):
        self._readers[name]()

    def _push_inputs(self, name):
        self._writers[name]()

    def _check_finite(self, t, names, during="its step"):
        """Raise SimulationError naming the first instance, in ``names`` order, whose
        outputs (or outputs read before stepping) are not finite.

        ``names`` is the order in which the instances ran (sources before the sinks
        that read them), so a NaN that spread through connections within one tick is
        blamed on the instance that produced it, not on the first one in the table.
        """
        n = self.n_bus
        watched = self.big[n:]
        if math.isfinite(float(watched.sum())):
            return
        for name in names:
            for (inst, var), i in self._slots_of(name):
                for region in (n, 2 * n):
                    x = float(self.big[region + i])
                    if not math.isfinite(x):
                        raise SimulationError(
                            f"instance {inst!r} produced {x!r} for {var} in {during} at "
                            f"t = {t!r} s (the FMI call itself returned OK)", inst, t)

    def _slots_of(self, name):
        cache = self.__dict__.setdefault("_slots_cache", {})
        if name not in cache:
            cache[name] = [(key, i) for key, i in self.slot.items() if key[0] == name]
        return cache[name]

    # -- compiled per-instance programs -------------------------------------------

    def _compile(self):
        """Build per-instance read/write closures with preallocated ctypes buffers."""
        n = self.n_bus
        big = self.big
        dbl_p = ctypes.POINTER(ctypes.c_double)
        base_addr = big.ctypes.data
        self._readers, self._writers, self._steps = {}, {}, {}
        self._pre_readers = {}
        keep = self._keep = []

        def reader_parts(s, reads, region):
            """Getter calls writing ``s``'s outputs into ``big[region:]`` (n or 2n)."""
            parts = []
            off, vs = reads["Real"]
            if vs:
                vr = (ctypes.c_uint32 * len(vs))(*[v.vr for v in vs])
                ptr = ctypes.cast(base_addr + 8 * (region + off), dbl_p)
                keep.extend((vr, ptr))
                parts.append(("R", s.getReal, vr, len(vs), ptr, None, None))
            for t, getter, ctype in (("Integer", s.getInteger, ctypes.c_int32),
                                     ("Boolean", s.getBoolean, ctypes.c_int32)):
                off, vs = reads[t]
                if vs:
                    vr = (ctypes.c_uint32 * len(vs))(*[v.vr for v in vs])
                    buf = (ctype * len(vs))()
                    view = np.frombuffer(buf, dtype=np.int32)
                    keep.extend((vr, buf))
                    parts.append(("I", getter, vr, len(vs), buf, view,
                                  slice(region + off, region + off + len(vs))))
            return parts

        for name, s in self.slaves.items():
            reads = self.reads[name]
            self._readers[name] = self._make_reader(s, reader_parts(s, reads, n))
            self._writers[name] = self._make_writer(s, self.inputs[name])
            if name in self.ft_sources:
                self._pre_readers[name] = self._make_reader(s, reader_parts(s, reads, 2 * n))

    def _make_reader(self, s, parts):
        comp = s.comp

        def read():
            for kind, fn, vr, nv, buf, view, sl in parts:
                st = fn(comp, vr, nv, buf)
                if st > 1:
                    raise self._fail(s, "reading outputs", self._now(), st)
                if kind == "I":
                    self.big[sl] = view
        return read

    def _make_writer(self, s, by_type):
        comp = s.comp
        big = self.big
        parts = []
        for t, setter in (("Real", s.setReal), ("Integer", s.setInteger),
                          ("Boolean", s.setBoolean)):
            items = by_type[t]
            if not items:
                continue
            vr = (ctypes.c_uint32 * len(items))(*[v.vr for v, *_ in items])
            idx = np.array([i for _, i, _, _ in items], dtype=np.intp)
            gain = np.array([g for _, _, g, _ in items])
            offset = np.array([o for _, _, _, o in items])
            scaled = bool(np.any(gain != 1.0) or np.any(offset != 0.0))
            fbuf = np.zeros(len(items))
            if t == "Real":
                buf, ibuf = fbuf, None
                ptr = fbuf.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
            else:
                buf = (ctypes.c_int32 * len(items))()
                ibuf = np.frombuffer(buf, dtype=np.int32)
                ptr = buf
            self._keep += [vr, fbuf, buf, ptr]
            parts.append((setter, vr, len(items), idx, gain, offset, scaled, fbuf, ibuf, ptr, t))

        def write():
            for setter, vr, nv, idx, gain, offset, scaled, fbuf, ibuf, ptr, t in parts:
                np.take(big, idx, out=fbuf)
                if scaled:
                    np.multiply(fbuf, gain, out=fbuf)
                    np.add(fbuf, offset, out=fbuf)
                if ibuf is not None:
                    ibuf[:] = (fbuf != 0) if t == "Boolean" else np.rint(fbuf)
                st = setter(comp, vr, nv, ptr)
                if st > 1:
                    raise self._fail(s, "setting inputs", self._now(), st)
        return write

    def _now(self):
        return self.plan.timebase.time(self.tick)

    # -- stepping ------------------------------------------------------------------

    def _step_program(self, name):
        """Return a function ``step(t)``: set inputs, doStep, read outputs."""
        write, advance = self._writers[name], self._advance_program(name)

        def step(t):
            write()
            advance(t)
        return step

    def _set_program(self, name):
        """Gauss-Seidel phase 1: set inputs at t_k; a feedthrough source then publishes
        its outputs at t_k (read before stepping) for its sinks."""
        write = self._writers[name]
        pre = self._pre_readers.get(name)
        if pre is None:
            return lambda t: write()

        def set_and_read(t):
            write()
            pre()
        return set_and_read

    def _advance_program(self, name):
        """doStep from t_k with the inputs already set, then read the outputs."""
        s = self.slaves[name]
        comp, do_step, h = s.comp, s.doStep, s.h
        read = self._readers[name]

        def advance(t):
            try:
                st = do_step(comp, t, h, 1)
            except Exception as exc:  # an FMU that raises through ctypes
                raise self._fail(s, "fmi2DoStep", t, exc=exc) from exc
            if st > 1:
                if st == 2 and s.asks_to_terminate():
                    raise _TerminationRequested(s.name, t, s.last_message())
                raise self._fail(s, "fmi2DoStep", t, st)
            read()
        return advance

    def _loop_program(self, members):
        """Return ``step(t, due)`` iterating an algebraic loop to a fixed point."""
        plan = self.plan
        loop = next(l for l in plan.loops if set(l.members) == set(members))
        steps = {m: self._step_program(m) for m in members}
        idx = np.array(sorted(
            self.n_bus + self.slot[(c.source, c.source_var)]
            for c in plan.feedthrough_edges if c.source in members and c.target in members))
        big, tol, max_it = self.big, self.loop_tolerance, self.max_iterations

        def step(t, due):
            states = {}
            try:
                for m in due:
                    states[m] = self.slaves[m].fmu.getFMUstate()
                prev = big[idx].copy()
                change = float("nan")
                for it in range(max_it):
                    for m in due:
                        steps[m](t)
                    new = big[idx]
                    if it > 0 and np.all(np.abs(new - prev) <= tol * (1.0 + np.abs(new))):
                        return
                    if it > 0:
                        change = float(np.max(np.abs(new - prev)))
                    prev = new.copy()
                    for m in due:
                        self.slaves[m].fmu.setFMUstate(states[m])
                raise AlgebraicLoopError(
                    f"algebraic loop {loop.describe()} did not converge in {max_it} "
                    f"iterations at t = {t!r} s (last change {change:.3g})")
            finally:
                for m, st in states.items():
                    try:
                        self.slaves[m].fmu.freeFMUstate(st)
                    except Exception:
                        pass
        return step

    def _schedule(self):
        """Per hyperperiod tick: a tuple of step callables in order."""
        plan, sc = self.plan, self.plan.scenario
        tb = plan.timebase
        if sc.experiment.algorithm == "jacobi":
            groups = [(i.name,) for i in sc.instances]
            loops = set()
        else:
            groups = plan.groups
            loops = {g for g in groups if len(g) > 1 or any(g == l.members for l in plan.loops)}
        progs, advance = {}, {}
        jacobi = sc.experiment.algorithm == "jacobi"
        for g in groups:
            if g in loops:
                progs[g] = self._loop_program(g)
            elif jacobi:
                progs[g] = self._step_program(g[0])
            else:
                progs[g] = self._set_program(g[0])
                advance[g] = self._advance_program(g[0])
        pt = tb.period_ticks
        slots = {m: [] for m in pt}
        for (m, _), i in self.slot.items():
            slots[m].append(i)

        def due_at(k):
            first, then, settle = [], [], []
            for g in groups:
                due = tuple(m for m in g if k % pt[m] == 0)
                if not due:
                    continue
                if g in loops:
                    first.append(_bind_loop(progs[g], due))
                elif jacobi:
                    then.append(progs[g])
                else:
                    first.append(progs[g])
                    settle.append(progs[g])
                    then.append(advance[g])
            # outputs stamped t_k: those of instances whose step ends now, i.e. due now
            due_all = [m for m in pt if k % pt[m] == 0]
            if len(due_all) == len(pt):
                snap_idx = None
            else:
                snap_idx = np.array(sorted(i for m in due_all for i in slots[m]), dtype=np.intp)
            # Gauss-Seidel: `first` sets inputs and reads feedthrough outputs at t_k (sources
            # first; loops are solved there), `then` steps; Jacobi: `then` does whole steps.
            # `settle` is what runs at the stop time: set/read only, no step.
            return snap_idx, tuple(first), tuple(then), tuple(settle)

        if tb.hyperperiod <= _MAX_PATTERN:
            cache, pattern = {}, []
            for k in range(tb.hyperperiod):
                key = tuple(k % pt[m] == 0 for m in pt)
                if key not in cache:
                    cache[key] = due_at(k)
                pattern.append(cache[key])
            return lambda k: pattern[k % tb.hyperperiod]
        return due_at

    def run(self, progress=None):
        """Step from start to stop, recording rows; raise SimulationError on failure.

        An FMU that asks to terminate (fmi2DoStep returns Discard and
        fmi2Terminated is true) ends the run normally at that communication point:
        the rows up to it are kept and :attr:`terminated` names the instance.

        Parameters
        ----------
        progress : callable, optional
            Called as ``progress(fraction)`` about every 2048 ticks.
        """
        plan, sc = self.plan, self.plan.scenario
        tb = plan.timebase
        schedule = self._schedule()
        n, big = self.n_bus, self.big
        cur = big[n:2 * n]
        watched = big[n:]  # outputs, and outputs read before stepping
        snap = big[:n]
        rec, rec_idx = self.rec, self.record_idx
        out_ticks = tb.output_ticks
        t0 = tb.start + 0 * tb.base
        # time(k) = (a + k*b) / d exactly rounded (Python int true division)
        d = t0.denominator * tb.base.denominator
        a = t0.numerator * tb.base.denominator
        b = tb.base.numerator * t0.denominator
        actions = self._actions()
        n_ticks = tb.n_ticks
        isfinite = math.isfinite
        order = [m for g in plan.groups for m in g]
        k = 0
        try:
            for k in range(n_ticks + 1):
                self.tick = k
                t = (a + k * b) / d
                snap_idx, first, then, settle = schedule(k)
                if snap_idx is None:
                    snap[:] = cur
                elif len(snap_idx):
                    snap[snap_idx] = cur[snap_idx]
                if k in actions:
                    for s, values in actions[k]:
                        s.set_values(values)
                for call in (settle if k == n_ticks else first):
                    call(t)
                if k % out_ticks == 0:
                    self.rows = k // out_ticks + 1
                    if len(rec_idx):
                        rec[self.rows - 1] = big[rec_idx]
                if k == n_ticks:
                    break
                for call in then:
                    call(t)
                if not isfinite(float(watched.sum())):
                    self._check_finite(t, order)
                if progress is not None and not k & 2047:
                    progress(k / n_ticks)
        except SimulationError:
            raise
        except AlgebraicLoopError as exc:
            raise SimulationError(str(exc), None, (a + k * b) / d) from exc
        except _TerminationRequested as req:
            self.terminated = (req.instance, req.time, req.message)
        if progress is not None:
            progress(1.0)

    def _actions(self):
        plan, sc = self.plan, self.plan.scenario
        out = {}
        for act in sc.actions:
            k = plan.timebase.ticks_of(act.time)
            per = {}
            for (inst, var), value in act.values.items():
                per.setdefault(inst, []).append((plan.fmus[inst].variables[var], value))
            out.setdefault(k, []).extend((self.slaves[i], vals) for i, vals in per.items())
        return out

    # -- results ---------------------------------------------------------------------

    def table(self) -> dict:
        """Recorded rows so far as ``{"time": array, "inst.var": array, ...}``."""
        out = {"time": self.times[: self.rows].copy()}
        for j, ref in enumerate(self.plan.scenario.record):
            out[ref] = self.rec[: self.rows, j].copy()
        return out

    def close(self):
        """Terminate and free every instance."""
        for s in self.slaves.values():
            s.close()
        self.slaves = {}
        gc.collect()  # free the slaves' Python leftovers while their callbacks exist


def _extracted(info: FmuInfo) -> str:
    """Folder of the FMU unpacked in the private cache, checked against its hash.

    Runs in one process reuse the folder, so the FMU's shared library is loaded once.
    """
    from fmutools.fmucache import extract_cached

    return str(extract_cached(info.path, info.sha256, kind="fmu"))


def _bind_loop(prog, due):
    def call(t):
        prog(t, due)
    return call


# ---------------------------------------------------------------------------------------
# Library entry point


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
        import fcntl

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
        from .results import write_metadata

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
        import pyarrow as pa
        import pyarrow.parquet as pq

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
        from .results import write_metadata, write_table

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
        import multiprocessing

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
                 quiet=True, csv=False, fmu_dir=None):
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
    from .results import package_versions
    from .scenario import load_scenario

    wall0 = _time.perf_counter()
    sc = load_scenario(scenario)
    sc = sc.with_overrides(overrides).with_experiment(stop=stop_time, algorithm=algorithm)
    plan = prepare(sc, fmu_dir)
    meta = {
        "scenario": sc.source,
        "scenario_sha256": sc.digest(),
        "algorithm": sc.experiment.algorithm,
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
    from .progress import ProgressBar
    from .results import RunResult

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
