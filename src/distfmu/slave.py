"""Disturbance FMU slave: a thin adapter over :mod:`distfmu.step`.

Variables
---------
parameters
    ``preset`` (String, fixed): a name of :data:`distfmu.presets.PRESETS`, e.g.
    ``"vnir_pointing"``, ``"swir_cryocooler"`` or ``"none"``, or ``"custom"``: the
    source stored in ``resources/source.json`` by :func:`distfmu.fmuspec.spec_with_source`;
    ``seed`` (Integer, fixed): 0 keeps the preset's phases, otherwise phases are drawn
    from it (:func:`distfmu.presets.randomized`);
    ``frequency_scale`` (1, fixed): factor on the source's line and repetition
    frequencies (:func:`distfmu.presets.retimed`; a source that does not repeat, or a
    wheel driven from ``wheel_speed``, takes 1 only);
    ``use_speed_input`` (Boolean, fixed): drive the ``rwa`` preset from ``wheel_speed``;
    ``scale`` (1), ``start_time`` and ``stop_time`` (s) (tunable): amplitude factor and
    active window ``[start_time, stop_time)``, ``stop_time <= start_time`` for no end.
input
    ``wheel_speed`` (rad/s), used only by a wheel preset with ``use_speed_input``.
outputs (no direct feedthrough)
    ``Fx, Fy, Fz`` (N) and ``Mx, My, Mz`` (N m) at the preset's mount.  Time-driven
    sources are functions of time only.  The input-driven wheel holds the speed over a
    step and outputs ``W(theta, Omega_held)`` at the end of it (see :mod:`distfmu.step`),
    so the outputs depend on ``wheel_speed`` only through the state.

The FMU state is every variable plus ``x = [time, theta, omega]``.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from distfmu.custom import CUSTOM_PRESET, SOURCE_FILE, CustomSourceError, source_from_json
from distfmu.presets import get_preset, randomized, retimed
from distfmu.sources import WRENCH_NAMES, SourceError
from distfmu.step import (DisturbanceConfig, DisturbanceState, disturbance_output,
                          disturbance_series, disturbance_step)
from fmukit.slave import FmuSlave
from fmukit.timing import end_time

__all__ = ["DisturbanceSlave"]


class DisturbanceSlave(FmuSlave):
    """One disturbance event at its mount.

    Class attributes
    ----------------
    default_preset : str
        Start value of the ``preset`` parameter.
    default_speed_input : bool
        Start value of the ``use_speed_input`` parameter.
    """

    default_preset: ClassVar[str] = "none"
    default_speed_input: ClassVar[bool] = False
    state_attributes = ("x",)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        p = self.add_parameter
        p("preset", str(self.default_preset),
          description="disturbance preset name, e.g. vnir_pointing, swir_cryocooler, none")
        p("seed", 0, description="0 keeps the preset phases; otherwise random phases")
        p("use_speed_input", bool(self.default_speed_input),
          description="drive a wheel preset from wheel_speed")
        p("scale", 1.0, unit="1", tunable=True, description="amplitude factor")
        p("start_time", 0.0, unit="s", tunable=True, description="start of the active window")
        p("stop_time", 0.0, unit="s", tunable=True,
          description="end of the active window; <= start_time for no end")
        self.add_input("wheel_speed", unit="rad/s",
                       description="wheel speed for the rwa preset")
        self.add_real_block("wrench", names=list(WRENCH_NAMES), causality="output",
                            unit=["N", "N", "N", "N.m", "N.m", "N.m"], depends_on=[],
                            description="force and torque on the spacecraft at the mount")
        # last, so that the variables before it keep their value references
        p("frequency_scale", 1.0, unit="1",
          description="factor on the source's line and repetition frequencies")
        self.x = np.zeros(3)
        self._source = None
        self._t0 = 0.0

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        """Record the start time, at which the initial state is made.

        Parameters
        ----------
        start_time : float
            Experiment start (s).
        stop_time : float, optional
            Stop time (s); not used (the active window is the ``stop_time`` parameter).
        tolerance : float, optional
            Not used.
        """
        self._t0 = float(start_time)

    def _config(self) -> DisturbanceConfig:
        if self._source is None:
            factor = float(self.frequency_scale)
            if factor != 1.0 and self.use_speed_input:
                raise SourceError("disturbance frequency_scale cannot scale a wheel driven "
                                  "from the wheel_speed input (its speed is the input's); "
                                  "leave frequency_scale at 1")
            self._source = randomized(retimed(self._preset_source(), factor),
                                      int(self.seed))
        stop = self.stop_time if self.stop_time > self.start_time else math.inf
        return DisturbanceConfig(self._source, scale=float(self.scale),
                                 start=float(self.start_time), stop=float(stop),
                                 speed_input=bool(self.use_speed_input))

    def _preset_source(self):
        if self.preset != CUSTOM_PRESET:
            return get_preset(self.preset).source
        path = self.resource_dir / SOURCE_FILE if self.resources is not None else None
        if path is None or not path.is_file():
            raise CustomSourceError(f"disturbance preset {CUSTOM_PRESET!r} needs the FMU's "
                                    f"own {SOURCE_FILE}; build the FMU with "
                                    "distfmu.fmuspec.spec_with_source")
        return source_from_json(path.read_bytes())

    def _state(self, time: float) -> DisturbanceState:
        return DisturbanceState(time=time, theta=float(self.x[1]), omega=float(self.x[2]))

    def _write(self, config: DisturbanceConfig, state: DisturbanceState,
               period: float = 0.0) -> None:
        self.x[:] = (state.time, state.theta, state.omega)
        self.wrench[:] = disturbance_output(config, state, period)

    def series(self, times) -> np.ndarray:
        """Outputs ``Fx .. Mz`` at the communication points ``times`` (s), shape (n, 6).

        The open-loop series of a time-driven source with the current parameters (see
        :func:`distfmu.step.disturbance_series`), for the linear engine.
        """
        return disturbance_series(self._config(), times)

    def exit_initialization_mode(self):
        self._source = None
        self._write(self._config(), DisturbanceState(time=self._t0))

    def do_step(self, current_time, step_size):
        """Advance the source, ``wheel_speed`` held; output the wrench.

        Parameters
        ----------
        current_time : float
            Communication point at the start of the step (s); taken as the exact time.
        step_size : float
            Step (s).

        Returns
        -------
        bool
            Always True.
        """
        config = self._config()
        state = disturbance_step(config, self._state(float(current_time)), step_size,
                                 float(self.wheel_speed))
        # the host's communication point, robust to its time arithmetic (fmukit.timing)
        self._write(config, DisturbanceState(end_time(current_time, step_size, self.x[0]), state.theta,
                                             state.omega), step_size)
        return True
