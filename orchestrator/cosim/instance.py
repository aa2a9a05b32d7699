"""One instantiated FMU bound to fmpy's raw FMI functions, and the process-wide logger.

An FMI 3.0 FMU is bound through :mod:`.fmi3`: the same raw handles, with FMI 2.0
signatures, so the master's loops run FMI 2.0 and 3.0 FMUs alike.
"""

from __future__ import annotations

import ctypes
import itertools
import math

import fmpy.fmi2 as f2
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2LastSuccessfulTime,
    fmi2Terminated,
)
from fmpy.logging import addLoggerProxy

from fmutools.fmucache import extract_cached

from .fmi3 import open_fmi3
from .fmuinfo import FmuInfo

__all__ = ["FmuInstance", "extracted"]

#: FMU objects whose shared libraries stay loaded for the life of the process.
_KEEP_LOADED: list = []


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


class FmuInstance:
    """One instantiated FMU with raw FMI function handles and precomputed arrays."""

    def __init__(self, name, info, unzipdir, instance_spec, timebase):
        self.name = name
        self.info = info
        self.messages = []
        self.period_ticks = timebase.period_ticks[name]
        p = instance_spec.period * 1  # Fraction
        self.h = p.numerator / p.denominator
        self.fmi3 = None
        if info.fmi_version == "3.0":
            self._open_fmi3(info, unzipdir, name)
            return
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
            addLoggerProxy(ctypes.byref(cb))
        except Exception:  # pragma: no cover - formatting proxy is optional
            pass
        self._log = None  # the shared logger lives in _LOGGER
        self._cb = cb
        self.instantiated = False
        self.fatal = False
        try:
            self.fmu.instantiate(callbacks=cb, loggingOn=True)
        except Exception as exc:  # fmpy's sentence names no cause
            said = " ".join(self.last_message().split())
            if not said:
                raise
            hint = ("; the model description and the binary come from different builds: "
                    "rebuild the FMU or use the one they came in") if "GUID" in said else ""
            raise RuntimeError(f"{exc}: the FMU says {said!r}{hint}") from exc
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
        self._getRealStatus = fn["fmi2GetRealStatus"]

    def _open_fmi3(self, info, unzipdir, name):
        """Bind an FMI 3.0 FMU: the same raw handles, through :mod:`.fmi3`'s shim."""
        self._cb = self._log = None
        self.instantiated = False
        self.fatal = False
        b = self.fmi3 = open_fmi3(info, unzipdir, name, self.messages)
        self.fmu = b.slave
        self.instantiated = True
        self.comp = b.comp
        self.getReal, self.setReal = b.getReal, b.setReal
        self.getInteger, self.setInteger = b.getInteger, b.setInteger
        self.getBoolean, self.setBoolean = b.getBoolean, b.setBoolean
        self.doStep = b.doStep

    def last_successful_time(self) -> float | None:
        """``fmi2GetRealStatus(fmi2LastSuccessfulTime)`` (s), or None if not answered;
        FMI 3.0: ``lastSuccessfulTime`` of the last ``fmi3DoStep``."""
        if self.fmi3 is not None:
            t = self.fmi3.last_successful_time()
            return t if math.isfinite(t) else None
        value = ctypes.c_double(0.0)
        try:
            st = self._getRealStatus(self.comp, fmi2LastSuccessfulTime, ctypes.byref(value))
        except Exception:
            return None
        return float(value.value) if st == 0 and math.isfinite(value.value) else None

    def asks_to_terminate(self) -> bool:
        """True if ``fmi2GetBooleanStatus(fmi2Terminated)`` answers fmi2OK and true.

        FMI 2.0 (4.2.3): after fmi2DoStep returned fmi2Discard, a slave that wants the
        simulation to end reports fmi2Terminated = true; any other answer (including
        an error from a slave that does not support the inquiry) means a failed step.
        """
        if self.fmi3 is not None:  # FMI 3.0: fmi3DoStep's terminateSimulation
            return self.fmi3.asks_to_terminate()
        value = ctypes.c_int(0)
        try:
            st = self._getBooleanStatus(self.comp, fmi2Terminated, ctypes.byref(value))
        except Exception:
            return False
        return st == 0 and bool(value.value)

    def ends_the_run(self) -> bool:
        """True if a Discard from fmi2DoStep is a normal end of the run, not a failure.

        The FMU must answer fmi2Terminated = true (:meth:`asks_to_terminate`) and must not
        have logged an error as its latest message: an FMU that logs an error and then
        declines the step (a Python FMU refusing a non-finite input or output does) has
        failed, whatever its terminated flag says.
        """
        if self.messages and self.messages[-1][0] >= 3:   # fmi2Error or fmi2Fatal
            return False
        return self.asks_to_terminate()

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
                if self.fmi3 is not None:
                    self.fmu.free()
                else:
                    self.fmu.fmi2FreeInstance(self.comp)
            except Exception:
                pass
            # keep the callbacks alive for the slave's leftovers collected later
            _KEEP_LOADED.append((self.fmu, self._cb, self._log))
            self.instantiated = False


def extracted(info: FmuInfo) -> str:
    """Folder of the FMU unpacked in the private cache, checked against its hash.

    Runs in one process reuse the folder, so the FMU's shared library is loaded once.
    """
    return str(extract_cached(info.path, info.sha256, kind="fmu"))
