"""The order of calls at each tick: which instances set, step and read, and when.

At tick ``k`` an instance with period ``p`` ticks is due when ``k % p == 0``.  Under
Gauss-Seidel a tick runs in two phases over the step groups of the plan (sources before
sinks): ``first`` sets every due instance's inputs and reads feedthrough outputs at
``t_k`` (algebraic loops are iterated to a fixed point there), then ``then`` steps them.
Under Jacobi ``then`` does whole steps (set, step, read) and every input reads the
snapshot at ``t_k``.  ``settle`` is what runs at the stop time: set and read, no step.
The due pattern repeats every hyperperiod, so it is computed once per distinct set of
due instances.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .bus import Bus
from .errors import TerminationRequested
from .graph import AlgebraicLoopError
from .plan import Plan

__all__ = ["Schedule"]

#: Largest hyperperiod for which the due pattern is precomputed (ticks).
MAX_PATTERN = 200_000


class Schedule:
    """Step programs of a compiled bus, and the per-tick order of calls.

    Parameters
    ----------
    plan : Plan
    bus : Bus
        Compiled (:meth:`Bus.compile`) for ``instances``.
    instances : dict of str to FmuInstance
    fail : callable
        ``fail(instance, what, t, status=None, exc=None)`` returns the SimulationError
        to raise.
    max_iterations : int
        Fixed-point iterations allowed per algebraic-loop solve.
    loop_tolerance : float
        Convergence test ``|x_new - x_old| <= tol * (1 + |x_new|)`` on loop signals.
    """

    def __init__(self, plan: Plan, bus: Bus, instances: dict, fail: Callable,
                 max_iterations: int, loop_tolerance: float):
        self.plan = plan
        self.bus = bus
        self.instances = instances
        self.fail = fail
        self.max_iterations = max_iterations
        self.loop_tolerance = loop_tolerance

    def step_program(self, name):
        """Return a function ``step(t)``: set inputs, doStep, read outputs."""
        write, advance = self.bus.writers[name], self.advance_program(name)

        def step(t):
            write()
            advance(t)
        return step

    def set_program(self, name):
        """Gauss-Seidel phase 1: set inputs at t_k; a feedthrough source then publishes
        its outputs at t_k (read before stepping) for its sinks."""
        write = self.bus.writers[name]
        pre = self.bus.pre_readers.get(name)
        if pre is None:
            return lambda t: write()

        def set_and_read(t):
            write()
            pre()
        return set_and_read

    def advance_program(self, name):
        """doStep from t_k with the inputs already set, then read the outputs."""
        s = self.instances[name]
        comp, do_step, h = s.comp, s.doStep, s.h
        read = self.bus.readers[name]
        fail = self.fail

        def advance(t):
            try:
                st = do_step(comp, t, h, 1)
            except Exception as exc:  # an FMU that raises through ctypes
                raise fail(s, "fmi2DoStep", t, exc=exc) from exc
            if st > 1:
                if st == 2 and s.ends_the_run():
                    raise TerminationRequested(s.name, t, s.last_message())
                raise fail(s, "fmi2DoStep", t, st)
            read()
        return advance

    def loop_program(self, members):
        """Return ``step(t, due)`` iterating an algebraic loop to a fixed point."""
        plan, bus = self.plan, self.bus
        loop = next(l for l in plan.loops if set(l.members) == set(members))
        steps = {m: self.step_program(m) for m in members}
        idx = np.array(sorted(
            bus.n + bus.slot[(c.source, c.source_var)]
            for c in plan.feedthrough_edges if c.source in members and c.target in members))
        values, tol, max_it = bus.values, self.loop_tolerance, self.max_iterations
        instances = self.instances

        def step(t, due):
            states = {}
            try:
                for m in due:
                    states[m] = instances[m].fmu.getFMUstate()
                prev = values[idx].copy()
                change = float("nan")
                for it in range(max_it):
                    for m in due:
                        steps[m](t)
                    new = values[idx]
                    if it > 0 and np.all(np.abs(new - prev) <= tol * (1.0 + np.abs(new))):
                        return
                    if it > 0:
                        change = float(np.max(np.abs(new - prev)))
                    prev = new.copy()
                    for m in due:
                        instances[m].fmu.setFMUstate(states[m])
                raise AlgebraicLoopError(
                    f"algebraic loop {loop.describe()} did not converge in {max_it} "
                    f"iterations at t = {t!r} s (last change {change:.3g})")
            finally:
                for m, st in states.items():
                    try:
                        instances[m].fmu.freeFMUstate(st)
                    except Exception:
                        pass
        return step

    def _groups(self):
        """``(groups, loops, jacobi)``: the step groups in order and those iterated."""
        plan, sc = self.plan, self.plan.scenario
        jacobi = sc.experiment.algorithm == "jacobi"
        if jacobi:
            return [(i.name,) for i in sc.instances], set(), True
        groups = plan.groups
        loops = {g for g in groups if len(g) > 1 or any(g == l.members for l in plan.loops)}
        return groups, loops, False

    def _calls(self, k, groups, loops, jacobi):
        """The calls of tick ``k``: ``(snap_idx, [(phase, kind, group, due)])``.

        ``phase`` is ``"first"``, ``"then"`` or ``"settle"``; ``kind`` is ``"loop"``,
        ``"step"`` (Jacobi: set, step, read), ``"set"`` (Gauss-Seidel phase 1) or
        ``"advance"`` (step and read).
        """
        pt = self.plan.timebase.period_ticks
        calls = []
        for g in groups:
            due = tuple(m for m in g if k % pt[m] == 0)
            if not due:
                continue
            if g in loops:
                calls.append(("first", "loop", g, due))
            elif jacobi:
                calls.append(("then", "step", g, due))
            else:
                calls.append(("first", "set", g, due))
                calls.append(("settle", "set", g, due))
                calls.append(("then", "advance", g, due))
        # outputs stamped t_k: those of instances whose step ends now, i.e. due now
        due_all = [m for m in pt if k % pt[m] == 0]
        if len(due_all) == len(pt):
            snap_idx = None
        else:
            slots = self._slots()
            snap_idx = np.array(sorted(i for m in due_all for i in slots[m]), dtype=np.intp)
        return snap_idx, calls

    def _slots(self):
        if not hasattr(self, "_slot_lists"):
            self._slot_lists = {m: [] for m in self.plan.timebase.period_ticks}
            for (m, _), i in self.bus.slot.items():
                self._slot_lists[m].append(i)
        return self._slot_lists

    def layout(self):
        """The hyperperiod pattern as names of calls, for the compiled loop.

        Returns
        -------
        tuple or None
            ``(programs, program_of_tick)``: ``programs`` a list of ``(snap_idx, first,
            then)`` with ``first`` and ``then`` lists of ``(kind, instance)`` (kind
            ``"set"``, ``"advance"`` or ``"step"``), ``program_of_tick`` the program
            number of each tick of the hyperperiod.  None when the schedule has an
            algebraic loop or no precomputed pattern (the Python loop runs then).
        """
        tb = self.plan.timebase
        groups, loops, jacobi = self._groups()
        if loops or tb.hyperperiod > MAX_PATTERN:
            return None
        pt = tb.period_ticks
        cache, programs, of_tick = {}, [], []
        for k in range(tb.hyperperiod):
            key = tuple(k % pt[m] == 0 for m in pt)
            if key not in cache:
                snap_idx, calls = self._calls(k, groups, loops, jacobi)
                cache[key] = len(programs)
                programs.append((snap_idx,
                                 [(kind, g[0]) for ph, kind, g, _ in calls if ph == "first"],
                                 [(kind, g[0]) for ph, kind, g, _ in calls if ph == "then"]))
            of_tick.append(cache[key])
        return programs, of_tick

    def pattern(self) -> Callable:
        """``at(k) -> (snap_idx, first, then, settle)`` for every tick ``k``.

        ``snap_idx`` is None when every instance is due (snapshot all of ``latest``),
        else the slots stamped ``t_k`` (those of the instances due now); ``first``,
        ``then`` and ``settle`` are tuples of ``call(t)``.
        """
        tb = self.plan.timebase
        groups, loops, jacobi = self._groups()
        progs = {}
        for g in groups:
            if g in loops:
                progs[("loop", g)] = self.loop_program(g)
            elif jacobi:
                progs[("step", g)] = self.step_program(g[0])
            else:
                progs[("set", g)] = self.set_program(g[0])
                progs[("advance", g)] = self.advance_program(g[0])
        pt = tb.period_ticks

        def due_at(k):
            # Gauss-Seidel: `first` sets inputs and reads feedthrough outputs at t_k (sources
            # first; loops are solved there), `then` steps; Jacobi: `then` does whole steps.
            # `settle` is what runs at the stop time: set/read only, no step.
            snap_idx, calls = self._calls(k, groups, loops, jacobi)
            phases = {"first": [], "then": [], "settle": []}
            for phase, kind, g, due in calls:
                prog = progs[(kind, g)]
                phases[phase].append(_bind_loop(prog, due) if kind == "loop" else prog)
            return snap_idx, tuple(phases["first"]), tuple(phases["then"]), \
                tuple(phases["settle"])

        if tb.hyperperiod <= MAX_PATTERN:
            cache, pattern = {}, []
            for k in range(tb.hyperperiod):
                key = tuple(k % pt[m] == 0 for m in pt)
                if key not in cache:
                    cache[key] = due_at(k)
                pattern.append(cache[key])
            return lambda k: pattern[k % tb.hyperperiod]
        return due_at


def _bind_loop(prog, due):
    def call(t):
        prog(t, due)
    return call
