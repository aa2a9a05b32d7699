"""The master's signal bus: every exchanged value in one float array, in three views.

Per instance the bus holds its Real outputs and recorded Reals, then its Integers and
Booleans (as floats), at fixed slots.  One array of ``3 n`` values carries three views:

* :attr:`Bus.snapshot` (``[:n]``) -- the values at the tick's time ``t_k`` (the latest
  stamped ``<= t_k``), taken at the start of the tick;
* :attr:`Bus.latest` (``[n:2n]``) -- the newest values, written after every step and
  iterated inside algebraic loops;
* :attr:`Bus.pre_step` (``[2n:]``) -- under Gauss-Seidel, the outputs of feedthrough
  sources read at ``t_k`` after their inputs were set and before they step (FMI: the
  outputs at ``t_k`` for the inputs at ``t_k``).

Each input reads one of these views, fixed once from the algorithm and the feedthrough
graph; :meth:`Bus.compile` turns the layout into per-instance read and write functions
over preallocated ctypes buffers, so a step costs a handful of raw FMI calls.
"""

from __future__ import annotations

import ctypes
from typing import Callable

import numpy as np

from .plan import Plan

__all__ = ["Bus", "RUNAWAY"]

#: Magnitude (SI units) beyond which any exchanged value means a run has diverged, for
#: outputs whose FMU declares no range: no physical quantity of a structure reaches it.
RUNAWAY = 1e100


class Bus:
    """Slots of a plan's exchanged values and the functions that move them.

    Parameters
    ----------
    plan : Plan
        From :func:`orchestrator.cosim.prepare`.

    Attributes
    ----------
    n : int
        Slots per view.
    values : ndarray, shape (3 n,)
        The three views back to back.
    slot : dict of (str, str) to int
        Slot of ``(instance, variable)`` within a view.
    ft_sources : set of str
        Instances whose feedthrough outputs are read before they step (Gauss-Seidel).
    inputs : dict of str to dict
        Per instance and FMI type: ``[(Variable, index into values, gain, offset)]``.
    record_idx : ndarray of int
        Index into ``values`` of each recorded variable, in the scenario's order.
    lo, hi : ndarray, shape (2 n,)
        Range of each value in :attr:`watched`: the FMU's declared ``min`` and ``max``,
        and :data:`RUNAWAY` in magnitude where it declares none.
    flags : list of (str, str)
        Saturation flags: discrete outputs named ``sat_*`` (1 while a rail or limit is
        active), at ``values[flag_idx]`` (the latest view).
    """

    def __init__(self, plan: Plan):
        sc = plan.scenario
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
        self.n = n
        self.values = np.zeros(3 * max(n, 1))
        in_loop = {m for g in plan.groups if len(g) > 1 for m in g}
        in_loop |= {l.members[0] for l in plan.loops}
        ft = {(c.source, c.source_var, c.target, c.target_var) for c in plan.feedthrough_edges}
        gs = sc.experiment.algorithm == "gauss-seidel"
        # sources of feedthrough edges outside algebraic loops: read before stepping;
        # so is an instance whose recorded output has feedthrough, connected or not (the
        # record holds the output at t_k for the inputs at t_k, as the FMI defines it)
        self.ft_sources = {c.source for c in plan.feedthrough_edges
                           if gs and c.source not in in_loop}
        for ref in sc.record:
            inst, var = ref.split(".", 1)
            if gs and inst not in in_loop and plan.fmus[inst].feedthrough.get(var):
                self.ft_sources.add(inst)
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
        self._slots_cache = {}
        self._bounds(plan)

    def _bounds(self, plan: Plan) -> None:
        """:attr:`lo`, :attr:`hi` and :attr:`flag_idx` from the FMUs' declarations."""
        n = self.n
        lo = np.full(2 * n, -RUNAWAY)
        hi = np.full(2 * n, RUNAWAY)
        lo[n:], hi[n:] = -np.inf, np.inf   # pre-step slots of instances read after stepping
        flags = []
        for (inst, var), i in self.slot.items():
            v = plan.fmus[inst].variables[var]
            regions = (0, n) if inst in self.ft_sources else (0,)
            for r in regions:
                lo[r + i] = max(v.min, -RUNAWAY)
                hi[r + i] = min(v.max, RUNAWAY)
            if v.name.startswith("sat_") and v.variability == "discrete":
                flags.append(((inst, var), n + i))
        self.lo, self.hi = lo, hi
        self.flags = [key for key, _ in flags]
        self.flag_idx = np.array([i for _, i in flags], dtype=np.intp)
        #: per flag, the ticks it was set after the tick's steps, and the first such tick
        self.flag_ticks = np.zeros(max(len(flags), 1), dtype=np.int64)
        self.flag_first = np.full(max(len(flags), 1), -1, dtype=np.int64)

    @property
    def snapshot(self) -> np.ndarray:
        """Values at the tick's time (a view of ``values[:n]``)."""
        return self.values[:self.n]

    @property
    def latest(self) -> np.ndarray:
        """Newest values (a view of ``values[n:2n]``)."""
        return self.values[self.n:2 * self.n]

    @property
    def watched(self) -> np.ndarray:
        """Every value an FMU produced: ``latest`` and ``pre_step`` (``values[n:]``)."""
        return self.values[self.n:]

    def slots_of(self, name: str) -> list:
        """``[((instance, variable), slot)]`` of one instance."""
        if name not in self._slots_cache:
            self._slots_cache[name] = [(key, i) for key, i in self.slot.items()
                                       if key[0] == name]
        return self._slots_cache[name]

    def compile(self, instances: dict, fail: Callable, now: Callable) -> None:
        """Build per-instance read and write functions with preallocated ctypes buffers.

        Parameters
        ----------
        instances : dict of str to FmuInstance
            The instantiated FMUs.
        fail : callable
            ``fail(instance, what, t, status)`` returns the SimulationError to raise when
            an FMI call returns a status above Warning.
        now : callable
            Current communication point (s).

        Afterwards :attr:`readers`, :attr:`writers` and :attr:`pre_readers` map an
        instance name to a function of no argument: read its outputs into ``latest``,
        set its inputs from the bus, read a feedthrough source's outputs into
        ``pre_step``.  :attr:`read_parts`, :attr:`pre_read_parts` and
        :attr:`write_parts` describe the same calls for the compiled loop: per instance
        ``[(type, getter, vr, nv, index into values)]`` and ``[(setter, vr, nv, idx,
        gain, offset, scaled, type)]``.
        """
        n = self.n
        dbl_p = ctypes.POINTER(ctypes.c_double)
        base_addr = self.values.ctypes.data
        self.readers, self.writers, self.pre_readers = {}, {}, {}
        self.read_parts, self.pre_read_parts, self.write_parts = {}, {}, {}
        keep = self._keep = []

        def read_desc(s, reads, region):
            out = []
            for t, getter in (("Real", s.getReal), ("Integer", s.getInteger),
                              ("Boolean", s.getBoolean)):
                off, vs = reads[t]
                if vs:
                    vr = (ctypes.c_uint32 * len(vs))(*[v.vr for v in vs])
                    keep.append(vr)
                    out.append((t, getter, vr, len(vs), region + off))
            return out

        def reader_parts(s, reads, region):
            """Getter calls writing ``s``'s outputs into ``values[region:]`` (n or 2n)."""
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

        for name, s in instances.items():
            reads = self.reads[name]
            self.readers[name] = self._make_reader(s, reader_parts(s, reads, n), fail, now)
            self.writers[name] = self._make_writer(s, self.inputs[name], fail, now)
            self.read_parts[name] = read_desc(s, reads, n)
            if name in self.ft_sources:
                self.pre_read_parts[name] = read_desc(s, reads, 2 * n)
                self.pre_readers[name] = self._make_reader(s, reader_parts(s, reads, 2 * n),
                                                           fail, now)

    def _make_reader(self, s, parts, fail, now):
        comp = s.comp
        values = self.values

        def read():
            for kind, fn, vr, nv, buf, view, sl in parts:
                st = fn(comp, vr, nv, buf)
                if st > 1:
                    raise fail(s, "reading outputs", now(), st)
                if kind == "I":
                    values[sl] = view
        return read

    def _make_writer(self, s, by_type, fail, now):
        comp = s.comp
        values = self.values
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
        self.write_parts[s.name] = [(setter, vr, nv, idx, gain, offset, scaled, t)
                                    for setter, vr, nv, idx, gain, offset, scaled, _, _, _, t
                                    in parts]

        def write():
            for setter, vr, nv, idx, gain, offset, scaled, fbuf, ibuf, ptr, t in parts:
                np.take(values, idx, out=fbuf)
                if scaled:
                    np.multiply(fbuf, gain, out=fbuf)
                    np.add(fbuf, offset, out=fbuf)
                if ibuf is not None:
                    ibuf[:] = (fbuf != 0) if t == "Boolean" else np.rint(fbuf)
                st = setter(comp, vr, nv, ptr)
                if st > 1:
                    raise fail(s, "setting inputs", now(), st)
        return write
