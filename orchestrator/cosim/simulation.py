"""Instantiate, initialise and step a prepared scenario; the master's run loop."""

from __future__ import annotations

import gc
import math
import os

import numpy as np

from .bus import RUNAWAY, Bus
from .errors import STATUS, DivergenceError, SimulationError, TerminationRequested
from .fastloop import RUN_FMI_STATUS, RUN_NOT_FINITE, RUN_OK, RUN_OUT_OF_RANGE, fast_loop
from .graph import AlgebraicLoopError, init_order
from .instance import FmuInstance, extracted
from .plan import Plan
from .schedule import Schedule

__all__ = ["Simulation"]


class Simulation:
    """Instantiate, initialise and step a prepared scenario.

    Parameters
    ----------
    plan : Plan
        From :func:`orchestrator.cosim.prepare`.
    max_iterations : int
        Fixed-point iterations allowed per algebraic-loop solve.
    loop_tolerance : float
        Convergence test ``|x_new - x_old| <= tol * (1 + |x_new|)`` on loop signals.
    fast : bool
        Step in the compiled loop when the schedule allows (bit-identical results);
        False always runs the Python loop.

    Examples
    --------
    >>> sim = Simulation(prepare(scenario))  # doctest: +SKIP
    >>> try:
    ...     sim.initialize(); sim.run()
    ... finally:
    ...     sim.close()
    >>> table = sim.table()
    """

    def __init__(self, plan: Plan, max_iterations: int = 100, loop_tolerance: float = 1e-12,
                 fast: bool = True):
        self.plan = plan
        self.fast = fast
        #: True when :meth:`run` stepped in the compiled loop
        self.compiled_loop = False
        self.max_iterations = max_iterations
        self.loop_tolerance = loop_tolerance
        self.slaves = {}
        self.rows = 0
        self.tick = 0
        #: ``(instance, time, message)`` when an FMU ended the run early (fmi2Terminated)
        self.terminated = None
        #: the terminating FMU's fmi2LastSuccessfulTime when a row was recorded there (s)
        self.last_successful_time = None
        self.bus = Bus(plan)
        tb = plan.timebase
        self.n_rows = tb.n_ticks // tb.output_ticks + 1
        self.rec = np.full((self.n_rows, len(plan.scenario.record)), np.nan)
        # tb.time(k) as (a + k b) / d with Python ints: the same correctly rounded value,
        # without a Fraction per row
        t0 = tb.start + 0 * tb.base
        d = t0.denominator * tb.base.denominator
        a = t0.numerator * tb.base.denominator
        b = tb.base.numerator * t0.denominator * tb.output_ticks
        self.times = np.array([(a + r * b) / d for r in range(self.n_rows)], dtype=float)

    # -- lifecycle -----------------------------------------------------------------

    def _fail(self, slave, what, t, status=None, exc=None):
        msg = f"instance {slave.name!r} failed in {what} at t = {t!r} s"
        if status is None and isinstance(getattr(exc, "status", None), int):
            status = exc.status  # fmpy's FMICallException carries the FMI status
        if status == 4 or any(st == 4 for st, _ in slave.messages):
            slave.fatal = True  # FMI 2.0: after fmi2Fatal no further call is allowed
        if status is not None:
            msg += f" with status {STATUS[status] if status < len(STATUS) else status}"
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
                unzipped[key] = extracted(info)
            # fmpy changes into the binary's folder to load it and does not change back
            # when the load fails: the caller's working folder is kept here
            cwd = os.getcwd()
            try:
                self.slaves[inst.name] = FmuInstance(inst.name, info, unzipped[key], inst,
                                                     plan.timebase)
            except Exception as exc:
                os.chdir(cwd)
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
        bus = self.bus
        bus.compile(self.slaves, self._fail, self._now)
        for name in order:  # sources first: a sink's inputs see initialised outputs
            s = self.slaves[name]
            try:
                self._read_all(order)
                bus.snapshot[:] = bus.latest
                bus.writers[name]()
                s.fmu.exitInitializationMode()
            except SimulationError:
                raise
            except Exception as exc:
                raise self._fail(s, "initialisation", t0, exc=exc) from exc
        self._read_all(order)
        bus.snapshot[:] = bus.latest
        for name in order:
            bus.writers[name]()
        self._check_finite(t0, order, "initialisation")
        self._check_range(t0, order, "initialisation")

    def _read_all(self, order):
        for name in order:
            self.bus.readers[name]()

    def _check_finite(self, t, names, during="its step"):
        """Raise SimulationError naming the first instance, in ``names`` order, whose
        outputs (or outputs read before stepping) are not finite.

        ``names`` is the order in which the instances ran (sources before the sinks
        that read them), so a NaN that spread through connections within one tick is
        blamed on the instance that produced it, not on the first one in the table.
        """
        bus = self.bus
        n = bus.n
        if math.isfinite(float(bus.watched.sum())):
            return
        for name in names:
            for (inst, var), i in bus.slots_of(name):
                for region in (n, 2 * n):
                    x = float(bus.values[region + i])
                    if not math.isfinite(x):
                        raise SimulationError(
                            f"instance {inst!r} produced {x!r} for {var} in {during} at "
                            f"t = {t!r} s (the FMI call itself returned OK)", inst, t)

    def _in_range(self) -> bool:
        w = self.bus.watched
        return not ((w < self.bus.lo).any() or (w > self.bus.hi).any())

    def _check_range(self, t, names, during="its step"):
        """Raise DivergenceError naming the first instance, in ``names`` order, with a
        value outside the range its FMU declares (or beyond :data:`RUNAWAY`)."""
        if self._in_range():
            return
        bus = self.bus
        n = bus.n
        for name in names:
            for (inst, var), i in bus.slots_of(name):
                for region in (0, n):
                    x = float(bus.values[n + region + i])
                    lo, hi = float(bus.lo[region + i]), float(bus.hi[region + i])
                    if lo <= x <= hi:
                        continue
                    v = self.plan.fmus[inst].variables[var]
                    unit = f" {v.unit}" if v.unit and v.unit != "1" else ""
                    if max(abs(lo), abs(hi)) >= RUNAWAY and abs(x) > RUNAWAY:
                        what = f"beyond {RUNAWAY:g} in magnitude"
                    else:
                        what = f"outside its declared range [{lo!r}, {hi!r}]{unit}"
                    raise DivergenceError(
                        f"instance {inst!r} produced {var} = {x!r}{unit}, {what}, in "
                        f"{during} at t = {t!r} s: the run diverged (an unstable loop or "
                        "model, e.g. too high a gain or negative damping); the rows up to "
                        "here are kept", inst, t)

    def saturation(self) -> list:
        """Saturation flags set during the run: ``[(instance, flag, seconds, first)]``.

        ``seconds`` is the time the flag (an FMU's discrete output ``sat_*``) was set
        after each tick's steps, counted on the base tick; ``first`` is the time of the
        first such tick (s).
        """
        tb = self.plan.timebase
        out = []
        for j, (inst, var) in enumerate(self.bus.flags):
            ticks = int(self.bus.flag_ticks[j])
            if ticks:
                out.append((inst, var, float(ticks * tb.base),
                            float(tb.time(int(self.bus.flag_first[j])))))
        return out

    def _now(self):
        return self.plan.timebase.time(self.tick)

    # -- stepping ------------------------------------------------------------------

    def run(self, progress=None):
        """Step from start to stop, recording rows; raise SimulationError on failure.

        An FMU that asks to terminate (fmi2DoStep returns Discard and
        fmi2Terminated is true) ends the run normally at that communication point:
        the rows up to it are kept and :attr:`terminated` names the instance.

        Without algebraic loops the ticks between actions run in compiled C
        (:mod:`orchestrator.cosim.fastloop`; ``fast=False`` or ``JITTERFMU_FAST_LOOP=0``
        turns this off), making the same calls with the same arithmetic.

        Parameters
        ----------
        progress : callable, optional
            Called as ``progress(fraction)`` about every 2048 ticks.
        """
        plan = self.plan
        tb = plan.timebase
        bus = self.bus
        sched = Schedule(plan, bus, self.slaves, self._fail, self.max_iterations,
                         self.loop_tolerance)
        schedule = sched.pattern()
        values = bus.values
        cur, watched, snap = bus.latest, bus.watched, bus.snapshot
        rec, rec_idx = self.rec, bus.record_idx
        out_ticks = tb.output_ticks
        t0 = tb.start + 0 * tb.base
        # time(k) = (a + k*b) / d exactly rounded (Python int true division)
        d = t0.denominator * tb.base.denominator
        a = t0.numerator * tb.base.denominator
        b = tb.base.numerator * t0.denominator
        actions = self._actions()
        n_ticks = tb.n_ticks
        isfinite = math.isfinite
        lo, hi = bus.lo, bus.hi
        flag_idx, flag_ticks, flag_first = bus.flag_idx, bus.flag_ticks, bus.flag_first
        n_flag = len(flag_idx)
        order = [m for g in plan.groups for m in g]
        fast = None
        if self.fast and os.environ.get("JITTERFMU_FAST_LOOP", "1") != "0":
            fast = fast_loop(sched.layout(), bus, self.slaves, tb, rec)
        self.compiled_loop = fast is not None
        action_ticks = sorted(k for k in actions if 0 <= k <= n_ticks)

        def python_tick(k):
            """One tick as the Python loop runs it; False after the last."""
            self.tick = k
            t = (a + k * b) / d
            snap_idx, first, then, settle = schedule(k)
            if snap_idx is None:
                snap[:] = cur
            elif len(snap_idx):
                snap[snap_idx] = cur[snap_idx]
            if k in actions:
                for s, vals in actions[k]:
                    s.set_values(vals)
            for call in (settle if k == n_ticks else first):
                call(t)
            if k % out_ticks == 0:
                self.rows = k // out_ticks + 1
                if len(rec_idx):
                    rec[self.rows - 1] = values[rec_idx]
            if k == n_ticks:
                return False
            for call in then:
                call(t)
            if not isfinite(float(watched.sum())):
                self._check_finite(t, order)
            if (watched < lo).any() or (watched > hi).any():
                self._check_range(t, order)
            if n_flag:
                on = values[flag_idx] != 0
                if on.any():
                    flag_ticks[:n_flag] += on
                    flag_first[:n_flag][(flag_first[:n_flag] < 0) & on] = k
            if progress is not None and not k & 2047:
                progress(k / n_ticks)
            return True

        k = 0
        try:
            if fast is None:
                for k in range(n_ticks + 1):
                    if not python_tick(k):
                        break
            else:
                next_action = 0
                while k <= n_ticks:
                    while next_action < len(action_ticks) and action_ticks[next_action] < k:
                        next_action += 1
                    stop = action_ticks[next_action] if next_action < len(action_ticks) \
                        else n_ticks
                    if k == stop:
                        if not python_tick(k):
                            break
                        k += 1
                        continue
                    # ticks k..k1 in C: up to the next progress tick, action or stop
                    k1 = min((k + 2047) & ~2047, stop - 1)
                    times = [(a + j * b) / d for j in range(k, k1 + 1)]
                    code = fast.run(k, k1, np.array(times), self.rows)
                    self.rows = fast.result.rows
                    if code != RUN_OK:
                        t = times[fast.result.tick - k]
                        k = self.tick = fast.result.tick
                    if code == RUN_FMI_STATUS:
                        self._fast_failure(fast, t)
                    elif code == RUN_NOT_FINITE:
                        self._check_finite(t, order)
                    elif code == RUN_OUT_OF_RANGE:
                        self._check_range(t, order)
                    else:
                        k = k1
                    self.tick = k
                    if progress is not None and not k & 2047:
                        progress(k / n_ticks)
                    k += 1
        except SimulationError:
            raise
        except AlgebraicLoopError as exc:
            raise SimulationError(str(exc), None, (a + k * b) / d) from exc
        except TerminationRequested as req:
            self.terminated = (req.instance, req.time, req.message)
            self._record_last_successful(req.instance)
        if progress is not None:
            progress(1.0)

    def _record_last_successful(self, name):
        """Record the row at the terminating FMU's ``fmi2LastSuccessfulTime``.

        An FMU that ends the run (Discard with fmi2Terminated) may have advanced inside
        the declined step, as the Reference FMU Stair does to the event that ends it;
        FMI hosts record its outputs there, and so does the master (the other instances
        keep their latest values).  Nothing is added when that time is not past the
        last recorded row.
        """
        s = self.slaves[name]
        t_last = s.last_successful_time()
        last_row = self.times[self.rows - 1] if self.rows else -math.inf
        tol = 1e-9 * float(self.plan.timebase.base)
        if t_last is None or not last_row + tol < t_last or self.rows >= self.n_rows:
            return
        try:
            self.bus.readers[name]()
        except SimulationError:
            return  # outputs not readable after the declined step: no row
        self.last_successful_time = t_last
        self.times[self.rows] = t_last
        self.rec[self.rows] = self.bus.latest[self.bus.record_idx % self.bus.n]
        self.rows += 1

    def _fast_failure(self, fast, t):
        """Raise what the Python loop raises for the compiled loop's failed FMI call."""
        s, what = fast.parts[fast.result.part]
        st = int(fast.result.status)
        if what == "fmi2DoStep":
            if st == 2 and s.ends_the_run():
                raise TerminationRequested(s.name, t, s.last_message())
            raise self._fail(s, what, t, st)
        raise self._fail(s, what, self._now(), st)

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
        # a Python FMU leaves Python objects behind: collect them now, while their
        # callbacks exist; the project's native FMUs (plain C) leave none, and the
        # collection was a quarter of a native run (0.05 s of the 8 s EOS case's 0.22 s)
        if not all(_plain_c(info) for info in self.plan.fmus.values()):
            gc.collect()


def _plain_c(info) -> bool:
    """Whether an FMU is one of the project's native (C only) FMUs or containers."""
    md = info.model_description
    return md is not None and str(getattr(md, "generationTool", "") or "").startswith(
        "jitterfmu nativefmu")
