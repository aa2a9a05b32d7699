"""Attitude control FMU slave: a thin adapter over :mod:`acsfmu.pid`.

Variables
---------
parameters (fixed)
    ``inertia_x, inertia_y, inertia_z`` (kg m^2) body inertias; ``bandwidth`` (Hz) loop
    crossover; ``bandwidth_x/y/z`` (Hz) per-axis crossover (0, the default: use
    ``bandwidth``); ``phase_margin`` (rad) design margin; ``sample_time`` (s) controller
    period (default 0.1 s, 10 Hz); ``torque_limit`` (N m) and ``momentum_limit``
    (N m s) per wheel; ``wheel_inertia`` (kg m^2); ``momentum0_x/y/z`` (N m s) initial
    wheel momenta; ``anti_windup`` (Boolean).  Gains come from
    :func:`acsfmu.design.pid_gains_for` at initialisation.
    Filters (:mod:`acsfmu.filters`, all off by default): ``notch_hz_x/y/z`` (Hz, 0 for
    none), ``notch_zeta_num_x/y/z`` (0.05), ``notch_zeta_den_x/y/z`` (0.5) on the
    commanded torque, then ``lowpass_hz_x/y/z`` (Hz, 0 for none), ``lowpass_zeta_x/y/z``
    (0.7); ``antialias_hz`` (Hz, 0 for none) and ``antialias_zeta`` (0.7) on the six
    inputs, at the controller's rate.
inputs
    ``roll, pitch, yaw`` (rad) attitude and ``rate_x, rate_y, rate_z`` (rad/s) body rates.
outputs (no direct feedthrough)
    ``Tx, Ty, Tz`` (N m) control torque on the body and ``wheel_speed_x/y/z`` (rad/s).

Timing: the controller samples at its own period ``sample_time`` on the grid
``n * sample_time``, whatever the communication step; all samples inside a step use
the inputs held over it, and a torque computed at a sample is applied one sample later
(one-sample computational delay).  Hence no output depends on an input within the same
communication point, and a master closing the attitude loop sees no algebraic loop.

The FMU state is every variable plus the 39-element controller, wheel and filter state
(:meth:`acsfmu.pid.AcsState.as_array`).
"""

from __future__ import annotations

import math
from dataclasses import replace

from acsfmu.design import pid_gains_for
from acsfmu.filters import AXES as _AXES
from acsfmu.pid import AcsConfig, AcsConfigError, AcsFilters, AcsState, PidGains, \
    acs_advance, acs_outputs, initial_state
from fmukit.slave import FmuSlave

__all__ = ["AcsSlave"]

#: Per-axis filter parameters: name, default, unit, description.
_AXIS_FILTERS = (
    ("notch_hz", 0.0, "Hz", "torque notch centre on {} (0 for none)"),
    ("notch_zeta_num", 0.05, "1", "torque notch numerator damping on {}"),
    ("notch_zeta_den", 0.5, "1", "torque notch denominator damping on {}"),
    ("lowpass_hz", 0.0, "Hz", "torque low-pass corner on {} (0 for none)"),
    ("lowpass_zeta", 0.7, "1", "torque low-pass damping on {}"),
)


class AcsSlave(FmuSlave):
    """Three-axis PID attitude control with reaction wheels."""

    state_attributes = ("x",)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        p = self.add_parameter
        for axis, j in zip(_AXES, (7600.0, 36000.0, 36000.0)):
            p(f"inertia_{axis}", j, unit="kg.m2", description=f"body inertia about {axis}")
        p("bandwidth", 0.1, unit="Hz", description="attitude loop crossover frequency")
        for axis in _AXES:
            p(f"bandwidth_{axis}", 0.0, unit="Hz",
              description=f"crossover on {axis} (0: use bandwidth)")
        p("phase_margin", math.radians(50.0), unit="rad",
          description="design phase margin of the sampled loop")
        p("sample_time", 0.1, unit="s", description="controller sample period")
        p("torque_limit", 0.4, unit="N.m", description="wheel torque limit per axis")
        p("momentum_limit", 75.0, unit="N.m.s", description="wheel momentum limit per axis")
        p("wheel_inertia", 0.2, unit="kg.m2", description="wheel rotor inertia")
        for axis in _AXES:
            p(f"momentum0_{axis}", 0.0, unit="N.m.s",
              description=f"initial wheel momentum on {axis}")
        p("anti_windup", True, description="freeze the integrator while saturated")
        for name, start, unit, description in _AXIS_FILTERS:
            for axis in _AXES:
                p(f"{name}_{axis}", start, unit=unit, description=description.format(axis))
        p("antialias_hz", 0.0, unit="Hz",
          description="anti-alias low-pass corner on the six inputs (0 for none)")
        p("antialias_zeta", 0.7, unit="1", description="anti-alias low-pass damping")
        self.add_real_block("attitude", names=["roll", "pitch", "yaw"], causality="input",
                            unit="rad", description="attitude angles")
        self.add_real_block("rate", names=["rate_x", "rate_y", "rate_z"], causality="input",
                            unit="rad/s", description="body rates")
        self.add_real_block("torque", names=["Tx", "Ty", "Tz"], causality="output",
                            unit="N.m", depends_on=[], description="control torque on the body")
        self.add_real_block("wheel_speed", names=[f"wheel_speed_{a}" for a in _AXES],
                            causality="output", unit="rad/s", depends_on=[],
                            description="wheel speed relative to the body")
        self.x = AcsState().as_array()
        self._cfg: AcsConfig | None = None
        self._t0 = 0.0

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        """Record the start time, at which the initial state is made.

        Parameters
        ----------
        start_time : float
            Start time (s).
        stop_time : float, optional
            Stop time (s); not used.
        tolerance : float, optional
            Not used.
        """
        self._t0 = float(start_time)

    def config(self) -> AcsConfig:
        """Controller configuration from the parameters (built once per instance)."""
        if self._cfg is None:
            inertia = [self.inertia_x, self.inertia_y, self.inertia_z]
            bandwidth = [getattr(self, f"bandwidth_{a}") or self.bandwidth for a in _AXES]
            try:
                gains = [pid_gains_for(j, bw, math.degrees(self.phase_margin),
                                       self.sample_time) for j, bw in zip(inertia, bandwidth)]
                kp, ki, kd = (list(g) for g in zip(*gains))
                filters = AcsFilters(float(self.sample_time), **{
                    name: [float(getattr(self, f"{name}_{a}")) for a in _AXES]
                    for name, *_ in _AXIS_FILTERS},
                    antialias_hz=float(self.antialias_hz),
                    antialias_zeta=float(self.antialias_zeta))
            except AcsConfigError as exc:
                raise AcsConfigError(f"ACS instance {self.instance_name!r}: {exc}") from None
            self._cfg = AcsConfig(PidGains(kp, ki, kd), sample_time=float(self.sample_time),
                                  torque_limit=float(self.torque_limit),
                                  momentum_limit=float(self.momentum_limit),
                                  wheel_inertia=float(self.wheel_inertia),
                                  anti_windup=bool(self.anti_windup), filters=filters)
        return self._cfg

    def _write(self, cfg: AcsConfig, state: AcsState) -> None:
        self.x[:] = state.as_array()
        torque, speed = acs_outputs(cfg, state)
        self.torque[:] = torque
        self.wheel_speed[:] = speed

    def exit_initialization_mode(self):
        self._cfg = None
        cfg = self.config()
        h0 = [self.momentum0_x, self.momentum0_y, self.momentum0_z]
        self._write(cfg, initial_state(cfg, self._t0, h0))

    def do_step(self, current_time, step_size):
        """Run the controller samples of the step, inputs held.

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
        cfg = self.config()
        # the master's communication point is the exact time; never accumulate
        state = replace(AcsState.from_array(self.x), time=float(current_time))
        state = acs_advance(cfg, state, float(step_size), self.attitude.copy(),
                            self.rate.copy())
        self._write(cfg, replace(state, time=float(current_time + step_size)))
        return True
