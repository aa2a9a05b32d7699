"""The master's tick loop compiled to C for the common case.

:class:`FastLoop` flattens a schedule's hyperperiod pattern (:meth:`Schedule.layout`)
into programs of raw FMI calls over the bus and runs ranges of ticks in ``fastloop.c``,
with the same calls in the same order and the same arithmetic as the Python loop of
:meth:`Simulation.run`, so the recorded tables are bit-identical.  It applies when the
schedule has no algebraic loop and a precomputed pattern, and every FMI function is a
ctypes function of a loaded library; :func:`fast_loop` answers None otherwise, and the
Python loop runs.  Actions and the last tick stay in Python.

The C file is compiled with gcc once per configuration into the private cache
(:func:`fmutools.fmucache.cache_root`), like the pythonfmu loader.
"""

from __future__ import annotations

import ctypes
import functools
from pathlib import Path

import numpy as np

from fmutools.compiled import c_library

__all__ = ["RUN_FMI_STATUS", "RUN_NOT_FINITE", "RUN_OK", "RUN_OUT_OF_RANGE", "FastLoop", "compiled_library",
           "fast_loop"]

SOURCE = Path(__file__).with_name("fastloop.c")

#: gcc flags: no fused multiply-add, so ``x * gain + offset`` rounds twice like numpy.
CFLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-fno-fast-math", "-fPIC", "-shared",
          "-Wall")
LIBS = ("-lm",)

RUN_OK, RUN_FMI_STATUS, RUN_NOT_FINITE, RUN_OUT_OF_RANGE = 0, 1, 2, 3
READ_REAL, READ_INT, SET_REAL, SET_INT, SET_BOOL, DO_STEP = range(6)

_i64p = ctypes.POINTER(ctypes.c_int64)
_dblp = ctypes.POINTER(ctypes.c_double)


class _Part(ctypes.Structure):
    _fields_ = [("kind", ctypes.c_int64), ("fn", ctypes.c_void_p), ("comp", ctypes.c_void_p),
                ("vr", ctypes.c_void_p), ("nv", ctypes.c_int64), ("start", ctypes.c_int64),
                ("idx", ctypes.c_void_p), ("gain", ctypes.c_void_p),
                ("offset", ctypes.c_void_p), ("scaled", ctypes.c_int64),
                ("fbuf", ctypes.c_void_p), ("ibuf", ctypes.c_void_p), ("h", ctypes.c_double)]


class _Loop(ctypes.Structure):
    _fields_ = [("values", ctypes.c_void_p), ("n", ctypes.c_int64), ("parts", ctypes.c_void_p),
                ("ops", ctypes.c_void_p), ("prog", ctypes.c_void_p),
                ("snap_idx", ctypes.c_void_p), ("prog_of_tick", ctypes.c_void_p),
                ("hyperperiod", ctypes.c_int64), ("output_ticks", ctypes.c_int64),
                ("rec", ctypes.c_void_p), ("rec_idx", ctypes.c_void_p),
                ("n_rec", ctypes.c_int64), ("lo", ctypes.c_void_p), ("hi", ctypes.c_void_p),
                ("flag_idx", ctypes.c_void_p), ("n_flag", ctypes.c_int64),
                ("flag_ticks", ctypes.c_void_p), ("flag_first", ctypes.c_void_p)]


class _Result(ctypes.Structure):
    _fields_ = [("tick", ctypes.c_int64), ("part", ctypes.c_int64),
                ("status", ctypes.c_int64), ("rows", ctypes.c_int64)]


@functools.cache
def compiled_library() -> ctypes.CDLL | None:
    """``fastloop.c`` compiled once per configuration, or None without a C compiler.

    The cache entry ``fastloop-<key>.so`` is keyed by a hash of the source, the
    compiler (path and version) and its flags; it is compiled in a temporary folder
    and renamed into place, so a killed build never leaves half a library.
    """
    lib = c_library("fastloop", SOURCE, CFLAGS, LIBS)
    if lib is None:   # no usable compiler: the Python loop runs
        return None
    lib.fastloop_run.argtypes = [ctypes.POINTER(_Loop), ctypes.c_int64, ctypes.c_int64,
                                 ctypes.c_void_p, ctypes.POINTER(_Result)]
    lib.fastloop_run.restype = ctypes.c_int
    return lib


def _address(fn) -> int | None:
    """Address of a ctypes foreign function, None for anything else (a Python stand-in)."""
    if not isinstance(fn, ctypes._CFuncPtr):
        return None
    return ctypes.cast(fn, ctypes.c_void_p).value


def flatten_programs(programs, part_of) -> tuple:
    """The hyperperiod's programs as the flat tables ``fastloop.c`` reads.

    Parameters
    ----------
    programs : sequence of (snapshot indices or None, calls, calls)
        From :meth:`Schedule.layout`: per program the bus slots to snapshot, the calls
        before the snapshot and those after.
    part_of : dict of (str, str) to list of int
        The part numbers of each call ``(kind, instance)``.

    Returns
    -------
    (ops, prog, snap) : tuple of list of int
        The parts in order; per program ``(first, middle, end, snap_start, snap_end)``;
        the snapshot slots.
    """
    ops, prog, snap = [], [], []
    for snap_idx, first, then in programs:
        p0 = len(ops)
        for call in first:
            ops.extend(part_of[call])
        mid = len(ops)
        for call in then:
            ops.extend(part_of[call])
        if snap_idx is None:
            s0 = s1 = -1
        else:
            s0 = len(snap)
            snap.extend(int(i) for i in snap_idx)
            s1 = len(snap)
        prog.extend((p0, mid, len(ops), s0, s1))
    return ops, prog, snap


class FastLoop:
    """Programs of raw FMI calls for every tick of the hyperperiod, run in C.

    Parameters
    ----------
    layout : tuple
        ``(programs, program_of_tick)`` from :meth:`Schedule.layout`.
    bus : Bus
        Compiled for ``instances``.
    instances : dict of str to FmuInstance
    timebase : Timebase
    rec : ndarray, shape (n_rows, n_record)
        Recorded rows, written in place.
    lib : ctypes.CDLL
        From :func:`compiled_library`.

    Attributes
    ----------
    parts : list of (FmuInstance, str)
        Per part, the instance and what its call does (for error messages).
    """

    def __init__(self, layout, bus, instances, timebase, rec, lib):
        programs, prog_of_tick = layout
        self.lib = lib
        self.parts = []
        keep = self._keep = []
        values = bus.values
        part_of = {}  # (kind, name) -> [part numbers]
        structs = []

        def add(kind, s, what, **fields):
            structs.append(dict(kind=kind, **fields))
            self.parts.append((s, what))
            return len(structs) - 1

        def arr(a, dtype):
            a = np.ascontiguousarray(a, dtype=dtype)
            keep.append(a)
            return a.ctypes.data

        for name, s in instances.items():
            sets = []
            for setter, vr, nv, idx, gain, offset, scaled, t in bus.write_parts[name]:
                kind = {"Real": SET_REAL, "Integer": SET_INT, "Boolean": SET_BOOL}[t]
                sets.append(add(kind, s, "setting inputs", fn=_address(setter), comp=s.comp,
                                vr=arr([vr[i] for i in range(nv)], np.uint32), nv=nv,
                                idx=arr(idx, np.int64), gain=arr(gain, np.float64),
                                offset=arr(offset, np.float64), scaled=int(scaled),
                                fbuf=arr(np.zeros(nv), np.float64),
                                ibuf=arr(np.zeros(nv, np.int32), np.int32)))

            def reads(desc, s=s):
                out = []
                for t, getter, vr, nv, start in desc:
                    out.append(add(READ_REAL if t == "Real" else READ_INT, s,
                                   "reading outputs", fn=_address(getter), comp=s.comp,
                                   vr=arr([vr[i] for i in range(nv)], np.uint32), nv=nv,
                                   start=start, ibuf=arr(np.zeros(nv, np.int32), np.int32)))
                return out
            step = [add(DO_STEP, s, "fmi2DoStep", fn=_address(s.doStep), comp=s.comp, h=s.h)]
            read = reads(bus.read_parts[name])
            pre = reads(bus.pre_read_parts.get(name, []))
            part_of[("set", name)] = sets + pre
            part_of[("advance", name)] = step + read
            part_of[("step", name)] = sets + step + read
        self.ok = all(p["fn"] is not None for p in structs) and all(
            getattr(s, "comp", None) is not None for s, _ in self.parts)
        if not self.ok:
            return
        arr_parts = (_Part * max(len(structs), 1))()
        for i, p in enumerate(structs):
            for key, v in p.items():
                setattr(arr_parts[i], key, v)
        keep.append(arr_parts)
        ops, prog, snap = flatten_programs(programs, part_of)
        self.rec = rec
        self.loop = _Loop(
            values=values.ctypes.data, n=bus.n, parts=ctypes.addressof(arr_parts),
            ops=arr(ops or [0], np.int64), prog=arr(prog, np.int64),
            snap_idx=arr(snap or [0], np.int64), prog_of_tick=arr(prog_of_tick, np.int64),
            hyperperiod=len(prog_of_tick), output_ticks=timebase.output_ticks,
            rec=rec.ctypes.data, rec_idx=arr(bus.record_idx, np.int64),
            n_rec=len(bus.record_idx), lo=arr(bus.lo, np.float64), hi=arr(bus.hi, np.float64),
            flag_idx=arr(bus.flag_idx if len(bus.flag_idx) else [0], np.int64),
            n_flag=len(bus.flag_idx), flag_ticks=bus.flag_ticks.ctypes.data,
            flag_first=bus.flag_first.ctypes.data)
        keep.append(values)
        self.result = _Result()

    def run(self, k0: int, k1: int, times: np.ndarray, rows: int) -> int:
        """Run ticks ``k0..k1`` (inclusive) in C.

        Parameters
        ----------
        k0, k1 : int
            First and last tick.
        times : ndarray, shape (k1 - k0 + 1,)
            ``times[k - k0]`` is the time of tick ``k`` (s), as the Python loop
            computes it.
        rows : int
            Rows recorded before ``k0``.

        Returns
        -------
        int
            RUN_OK, or RUN_FMI_STATUS / RUN_NOT_FINITE with :attr:`result` telling the
            tick (and the failed part and its FMI status); ``result.rows`` counts the
            recorded rows.
        """
        self.result.rows = rows
        return self.lib.fastloop_run(ctypes.byref(self.loop), k0, k1, times.ctypes.data,
                                     ctypes.byref(self.result))


def fast_loop(layout, bus, instances, timebase, rec) -> FastLoop | None:
    """A :class:`FastLoop` for ``layout``, or None when the Python loop must run.

    Parameters
    ----------
    layout : tuple or None
        From :meth:`Schedule.layout` (None: the schedule needs the Python loop).
    bus : Bus
        Compiled for ``instances``.
    instances : dict of str to FmuInstance
    timebase : Timebase
    rec : ndarray, shape (n_rows, n_record)
        Recorded rows, written in place.

    Returns
    -------
    FastLoop or None
        None without a C compiler, or when an FMI function is not a ctypes function.
    """
    if layout is None or not rec.flags.c_contiguous:
        return None
    lib = compiled_library()
    if lib is None:
        return None
    loop = FastLoop(layout, bus, instances, timebase, rec, lib)
    return loop if loop.ok else None
