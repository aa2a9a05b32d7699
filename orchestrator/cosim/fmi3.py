"""An FMI 3.0 co-simulation FMU behind the calls the master makes of an FMI 2.0 one.

The master's loops (the bus readers and writers, :mod:`.schedule`, the compiled loop
``fastloop.c``) call raw ``fmi2GetReal``-style functions ``f(comp, vr, n, values)`` and
``fmi2DoStep(comp, t, h, 1)``.  :func:`open_fmi3` instantiates an FMI 3.0 FMU with
fmpy's :class:`~fmpy.fmi3.FMU3Slave` and hands back functions of exactly those
signatures, from ``fmi3shim.c`` (compiled once into the private cache, like the
compiled loop): each forwards to ``fmi3GetFloat64``, ``fmi3SetInt32``, ``fmi3DoStep``...
with the same values, so a scenario mixes FMI 2.0 and 3.0 FMUs and both loops run it
with one arithmetic.  Without a C compiler the same functions are Python closures over
the ctypes calls, and the Python loop runs.

The slow calls (initialisation, start values, FMU state, termination) go through
:class:`Fmi3Slave`, which names them as fmpy's :class:`~fmpy.fmi2.FMU2Slave` does.
"""

from __future__ import annotations

import ctypes
import functools
import itertools
from pathlib import Path

from fmpy.fmi3 import (
    FMU3Slave,
    fmi3IntermediateUpdateCallback,
    fmi3LogMessageCallback,
    fmi3ValueReference,
)

from fmutools.compiled import c_library

__all__ = ["Fmi3Binding", "Fmi3Slave", "open_fmi3", "shim_library"]

SOURCE = Path(__file__).with_name("fmi3shim.c")
CFLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-Wall")

_LOG_KEYS = itertools.count(1)
_LOG_SINKS: dict[int, list] = {}
_LOGGER: list = []


def _shared_logger():
    """The one fmi3LogMessageCallback of the process (created once, never freed)."""
    if not _LOGGER:
        def log(env, status, category, message):
            sink = _LOG_SINKS.get(env or 0)
            if sink is None:
                return
            sink.append((status, message.decode("utf-8", "replace") if message else ""))
            del sink[:-20]

        _LOGGER.append(fmi3LogMessageCallback(log))
    return _LOGGER[0]


class _Shim(ctypes.Structure):
    _fields_ = [("instance", ctypes.c_void_p), ("get_f64", ctypes.c_void_p),
                ("set_f64", ctypes.c_void_p), ("get_i32", ctypes.c_void_p),
                ("set_i32", ctypes.c_void_p), ("get_bool", ctypes.c_void_p),
                ("set_bool", ctypes.c_void_p), ("do_step", ctypes.c_void_p),
                ("bbuf", ctypes.c_void_p), ("n_bbuf", ctypes.c_int64),
                ("terminate", ctypes.c_int64), ("event", ctypes.c_int64),
                ("last_time", ctypes.c_double)]


@functools.cache
def shim_library() -> ctypes.CDLL | None:
    """``fmi3shim.c`` compiled once per configuration, or None without a C compiler."""
    lib = c_library("fmi3shim", SOURCE, CFLAGS)
    if lib is None:
        return None
    vp, sz, u32p = ctypes.c_void_p, ctypes.c_size_t, ctypes.POINTER(ctypes.c_uint32)
    for name, values in (("real", ctypes.POINTER(ctypes.c_double)),
                         ("int", ctypes.POINTER(ctypes.c_int32)),
                         ("bool", ctypes.POINTER(ctypes.c_int32))):
        for op in ("get", "set"):
            fn = getattr(lib, f"shim_{op}_{name}")
            fn.argtypes = [vp, u32p, sz, values]
            fn.restype = ctypes.c_int
    lib.shim_do_step.argtypes = [vp, ctypes.c_double, ctypes.c_double, ctypes.c_int]
    lib.shim_do_step.restype = ctypes.c_int
    return lib


class Fmi3Slave:
    """An instantiated FMI 3.0 FMU with the slow-path methods of fmpy's FMU2Slave.

    Parameters
    ----------
    fmu : FMU3Slave
        Loaded and instantiated (``fmu.component`` set).
    """

    def __init__(self, fmu: FMU3Slave):
        self.fmu = fmu
        self.component = fmu.component
        self._start, self._stop = 0.0, None

    def setupExperiment(self, startTime=0.0, stopTime=None, tolerance=None):
        """Keep the experiment for :meth:`enterInitializationMode`.

        FMI 3.0 has no setup call of its own.

        Parameters
        ----------
        startTime : float
            Start time (s).
        stopTime : float, optional
            Stop time (s); None if undefined.
        tolerance : float, optional
            Relative tolerance; None if undefined.
        """
        self._start, self._stop, self._tolerance = startTime, stopTime, tolerance

    def enterInitializationMode(self):
        self.fmu.enterInitializationMode(tolerance=getattr(self, "_tolerance", None),
                                         startTime=self._start, stopTime=self._stop)

    def exitInitializationMode(self):
        self.fmu.exitInitializationMode()

    def setReal(self, vr, values):
        """``fmi3SetFloat64`` (raises on an error status).

        Parameters
        ----------
        vr : sequence of int
            Value references.
        values : sequence
            One value per value reference.
        """
        self.fmu.setFloat64(vr, values)

    def setInteger(self, vr, values):
        """``fmi3SetInt32`` (raises on an error status).

        Parameters
        ----------
        vr : sequence of int
            Value references.
        values : sequence
            One value per value reference.
        """
        self.fmu.setInt32(vr, values)

    def setBoolean(self, vr, values):
        """``fmi3SetBoolean`` (raises on an error status).

        Parameters
        ----------
        vr : sequence of int
            Value references.
        values : sequence
            One value per value reference.
        """
        self.fmu.setBoolean(vr, values)

    def setString(self, vr, values):
        """``fmi3SetString`` (raises on an error status).

        Parameters
        ----------
        vr : sequence of int
            Value references.
        values : sequence
            One value per value reference.
        """
        self.fmu.setString(vr, values)

    def getFMUstate(self):
        return self.fmu.getFMUState()

    def setFMUstate(self, state):
        self.fmu.setFMUState(state)

    def freeFMUstate(self, state):
        self.fmu.freeFMUState(state)

    def serializeFMUstate(self, state) -> bytes:
        return self.fmu.serializeFMUState(state)

    def deSerializeFMUstate(self, data: bytes):
        return self.fmu.deserializeFMUState(data)

    def terminate(self):
        self.fmu.terminate()

    def free(self):
        """Free the instance, keeping the shared library loaded."""
        self.fmu.fmi3FreeInstance(self.component)


class Fmi3Binding:
    """The raw FMI 2.0-style handles of one FMI 3.0 instance (see the module docstring).

    Attributes
    ----------
    slave : Fmi3Slave
    comp : int
        Address of the shim's context: the ``comp`` every handle takes.
    getReal, setReal, getInteger, setInteger, getBoolean, setBoolean, doStep : callable
    """

    def __init__(self, fmu: FMU3Slave, n_boolean: int):
        self.slave = Fmi3Slave(fmu)
        fn = fmu._functions
        raw = {key: fn[name] for key, name in (
            ("get_f64", "fmi3GetFloat64"), ("set_f64", "fmi3SetFloat64"),
            ("get_i32", "fmi3GetInt32"), ("set_i32", "fmi3SetInt32"),
            ("get_bool", "fmi3GetBoolean"), ("set_bool", "fmi3SetBoolean"),
            ("do_step", "fmi3DoStep"))}
        self._bbuf = (ctypes.c_bool * max(n_boolean, 1))()
        self.shim = _Shim(instance=fmu.component, bbuf=ctypes.addressof(self._bbuf),
                          n_bbuf=len(self._bbuf), last_time=float("nan"),
                          **{k: ctypes.cast(f, ctypes.c_void_p).value
                             for k, f in raw.items()})
        self.comp = ctypes.addressof(self.shim)
        lib = shim_library()
        if lib is not None:
            self.getReal, self.setReal = lib.shim_get_real, lib.shim_set_real
            self.getInteger, self.setInteger = lib.shim_get_int, lib.shim_set_int
            self.getBoolean, self.setBoolean = lib.shim_get_bool, lib.shim_set_bool
            self.doStep = lib.shim_do_step
        else:
            self._python_handles(raw)

    def _python_handles(self, raw):
        """The handles as Python closures over the ctypes calls (no C compiler)."""
        inst, shim, bbuf = self.shim.instance, self.shim, self._bbuf

        def plain(f):
            return lambda comp, vr, n, values: f(inst, vr, n, values, n)

        def get_bool(comp, vr, n, values):
            st = raw["get_bool"](inst, vr, n, bbuf, n)
            for i in range(n):
                values[i] = int(bbuf[i])
            return st

        def set_bool(comp, vr, n, values):
            for i in range(n):
                bbuf[i] = values[i] != 0
            return raw["set_bool"](inst, vr, n, bbuf, n)

        def do_step(comp, t, h, no_set_prior):
            flags = [ctypes.c_bool(False) for _ in range(3)]
            last = ctypes.c_double(t)
            st = raw["do_step"](inst, t, h, bool(no_set_prior), *map(ctypes.byref, flags),
                                ctypes.byref(last))
            shim.event, shim.terminate, shim.last_time = (int(flags[0].value),
                                                          int(flags[1].value), last.value)
            return st

        self.getReal, self.setReal = plain(raw["get_f64"]), plain(raw["set_f64"])
        self.getInteger, self.setInteger = plain(raw["get_i32"]), plain(raw["set_i32"])
        self.getBoolean, self.setBoolean, self.doStep = get_bool, set_bool, do_step

    def last_successful_time(self) -> float:
        """``lastSuccessfulTime`` of the last ``fmi3DoStep`` (s); NaN before one."""
        return float(self.shim.last_time)

    def asks_to_terminate(self) -> bool:
        """``terminateSimulation`` of the last ``fmi3DoStep``."""
        return bool(self.shim.terminate)


def open_fmi3(info, unzipdir: str, name: str, messages: list) -> Fmi3Binding:
    """Load and instantiate an FMI 3.0 co-simulation FMU for the master.

    Parameters
    ----------
    info : FmuInfo
        Its model description (``fmi_version == "3.0"``).
    unzipdir : str
        The unpacked FMU.
    name : str
        Instance name.
    messages : list
        Receives ``(status, text)`` of every message the instance logs (the last 20).

    Returns
    -------
    Fmi3Binding

    Raises
    ------
    RuntimeError
        If the FMU refuses to instantiate, with what it logged.
    """
    fmu = FMU3Slave(guid=info.guid, unzipDirectory=unzipdir,
                    modelIdentifier=info.model_identifier, instanceName=name)
    key = next(_LOG_KEYS)
    _LOG_SINKS[key] = messages
    fmu.logMessage = _shared_logger()
    fmu.intermediateUpdate = fmi3IntermediateUpdateCallback()
    resources = str(Path(unzipdir) / "resources") + "/"
    fmu.component = fmu.fmi3InstantiateCoSimulation(
        name.encode(), info.guid.encode(), resources.encode(), False, True, False, False,
        (fmi3ValueReference * 0)(), 0, ctypes.c_void_p(key), fmu.logMessage,
        fmu.intermediateUpdate)
    if not fmu.component:
        bad = [m for s, m in messages if s >= 1 and m]
        said = f": the FMU says {bad[-1]!r}" if bad else ""
        raise RuntimeError(f"fmi3InstantiateCoSimulation of {info.path.name} failed{said}")
    n_boolean = sum(v.type == "Boolean" for v in info.variables.values())
    return Fmi3Binding(fmu, n_boolean)
