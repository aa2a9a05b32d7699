"""Piezo actuator + amplifier FMU slave: a thin adapter over `piezofmu.actuator.step`.

One FMU per stack preset (the generated slave class sets `PiezoSlave.preset_name`).

Variables
---------
inputs
    ``v_cmd`` (V) voltage command, held over a step; ``elongation`` (m) of the active member.
outputs (direct feedthrough from ``v_cmd``, and from ``elongation`` through the servo)
    ``force`` (N): with ``coupling = 1`` (the default) the mean force over the coming
    step of ``hold_step`` with ``v_cmd`` held (`piezofmu.actuator.step_mean`), the force a
    structure holding it over that step must see so that a command reaches it after the
    amplifier's lag and not one whole step late; recomputed whenever ``v_cmd`` is set and
    after every step.  With ``coupling = 0`` the force at the end of the last step (the
    earlier coupling, kept for comparison: it adds one step of delay to every loop).
outputs (no direct feedthrough: functions of the state)
    ``voltage`` (V), ``current`` (A), ``free_stroke`` (m),
    ``sat_voltage``, ``sat_slew``, ``sat_stroke`` (Real 0/1).
outputs (direct feedthrough from ``elongation``)
    ``strain`` (-): recomputed whenever an input is set, so a Gauss–Seidel master reads the
    strain of the elongation it has just set.
parameters
    amplifier, hysteresis, stroke-limit, strain-gauge and servo settings (see
    `PiezoSlave`); the voltage and current limits, stroke limit and gauge noise are
    tunable between steps.  ``servo_bandwidth`` > 0 (Hz) closes the stack's built-in
    servo loop on ``elongation`` (`piezofmu.actuator`); 0, the default, leaves it open.

The FMU state is every variable plus the actuator state array
(`piezofmu.actuator.ActuatorState.to_array`).
"""

from __future__ import annotations

import math
from typing import ClassVar

from fmukit.slave import FmuSlave
from fmukit.timing import same_step
from fmukit.units import MAX_STRAIN
from piezofmu import actuator as ac
from piezofmu.actuator import DEFAULT_BOUC_WEN, ActuatorState, PiezoActuator, StrainGauge
from piezofmu.hysteresis import BoucWen

__all__ = ["PiezoSlave", "PiezoParameterError"]

_FLAGS = ("sat_voltage", "sat_slew", "sat_stroke")


class PiezoParameterError(ValueError):
    """An FMU parameter of the piezo slave is out of range."""


class PiezoSlave(FmuSlave):
    """Piezo stack with its amplifier, hysteresis, stroke limit and strain gauge.

    Class attributes
    ----------------
    preset_name : str
        Stack preset of `piezofmu.actuator.ACTUATORS` giving the datasheet values and the
        default parameters.
    """

    preset_name: ClassVar[str] = "P-243.30"
    state_attributes = ("x",)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        base = ac.actuator_preset(self.preset_name)
        amp, gauge = base.amplifier, base.gauge
        p = self.add_parameter
        p("v_min", float(amp.v_min), unit="V", tunable=True, description="lower voltage rail")
        p("v_max", float(amp.v_max), unit="V", tunable=True, description="upper voltage rail")
        p("i_max", float(amp.i_max), unit="A", tunable=True,
          description="amplifier current limit (slew limit i_max / C)")
        p("bandwidth", float(amp.bandwidth), unit="Hz",
          description="amplifier cut-off (order 1) or natural (order 2) frequency")
        p("amp_order", int(amp.order), description="order of the amplifier low-pass, 1 or 2")
        p("damping", float(amp.damping), unit="1",
          description="damping ratio of the second-order low-pass")
        p("internal_step", float(amp.internal_step), unit="s",
          description="fixed internal sub-step of the amplifier")
        p("hysteresis", False, description="Bouc-Wen hysteresis on")
        p("bw_alpha", DEFAULT_BOUC_WEN[0], unit="1", description="Bouc-Wen alpha")
        p("bw_beta_v0", DEFAULT_BOUC_WEN[1], unit="1",
          description="Bouc-Wen beta times the rated voltage")
        p("bw_gamma_v0", DEFAULT_BOUC_WEN[2], unit="1",
          description="Bouc-Wen gamma times the rated voltage")
        p("stroke_limit", 0.0, unit="m", tunable=True,
          description="free-stroke magnitude limit, 0 for none")
        p("gauge_length", float(gauge.length), unit="m", description="strain gauge length")
        p("noise_std", 0.0, unit="1", tunable=True,
          description="strain gauge noise standard deviation")
        p("resolution", 0.0, unit="1", description="strain quantisation step, 0 for none")
        p("seed", 0, description="seed of the strain gauge noise, >= 0")
        p("servo_bandwidth", 0.0, unit="Hz", description="crossover of the stack's built-in "
          "servo loop on the measured expansion (elongation); 0 for no servo")
        p("servo_plant_gain", 0.0, unit="m/V", description="expansion per volt of the "
          "mounted stack at low frequency that the servo is set for; 0 for d0/V0")
        p("coupling", 1, description="force held by the structure: 1 = mean force over the "
          "coming step of hold_step with v_cmd held (feedthrough, no added delay); 0 = "
          "force at the end of the last step (one step of delay, for comparison)")
        p("hold_step", 1e-3, unit="s", description="communication step of this FMU, over "
          "which the structure holds the force (coupling = 1 steps only with it)")
        self.add_input("v_cmd", unit="V", description="voltage command to the amplifier")
        self.add_input("elongation", unit="m", description="active-member elongation")
        self.add_output("force", unit="N", depends_on=["v_cmd", "elongation"],
                        description="actuator force on the structure f_c = c h v_eff, "
                        "held over the step (coupling = 1: its mean over the coming step)")
        self.add_output("voltage", unit="V", depends_on=[], description="applied voltage")
        self.add_output("current", unit="A", depends_on=[],
                        description="amplifier current C dv/dt")
        self.add_output("free_stroke", unit="m", depends_on=[],
                        description="free stroke d0/V0 v_eff after the stroke limit")
        self.add_output("strain", unit="1", depends_on=["elongation"],
                        description="strain gauge reading elongation / gauge_length + noise")
        self.declare_range("strain", -MAX_STRAIN, MAX_STRAIN)
        for flag, what in zip(_FLAGS, ("voltage rail", "current (slew) limit", "stroke limit")):
            self.add_output(flag, unit="1", depends_on=[], variability="discrete",
                            description=f"1 when the {what} is active, else 0")
        self.x = ActuatorState().to_array()
        self._stack = base.stack
        self._key = None
        self._act: PiezoActuator | None = None
        self._ready = False
        self._ahead = None   # (key, state, outputs, mean force) of the coming step
        self._force_stale = False   # force to refresh before it is read

    # ---------------------------------------------------------------- model
    def _parameter_key(self) -> tuple:
        return (self.v_min, self.v_max, self.i_max, self.bandwidth, self.amp_order,
                self.damping, self.internal_step, self.hysteresis, self.bw_alpha,
                self.bw_beta_v0, self.bw_gamma_v0, self.stroke_limit, self.gauge_length,
                self.noise_std, self.resolution, self.seed, self.servo_bandwidth,
                self.servo_plant_gain)

    def actuator(self) -> PiezoActuator:
        """The actuator model for the current parameter values (rebuilt when they change)."""
        key = self._parameter_key()
        if key != self._key:
            self._act = self._build(key)
            self._key = key
        return self._act

    def _build(self, key) -> PiezoActuator:
        (v_min, v_max, i_max, bandwidth, order, damping, h, hyst, alpha, beta_v0, gamma_v0,
         stroke_limit, gauge_length, noise_std, resolution, seed, servo_hz, servo_g) = key
        if stroke_limit < 0:
            raise PiezoParameterError(f"parameter stroke_limit of {self.instance_name!r} is "
                                      f"{stroke_limit!r}; expected >= 0 (0 for no limit)")
        base = ac.actuator_preset(self.preset_name)
        amp = base.amplifier.replace(v_min=float(v_min), v_max=float(v_max),
                                     i_max=float(i_max), bandwidth=float(bandwidth),
                                     order=int(order), damping=float(damping),
                                     internal_step=float(h))
        v0 = self._stack.rated_voltage
        bw = BoucWen.scaled(float(alpha), float(beta_v0), float(gamma_v0), v0) if hyst else None
        gauge = StrainGauge(float(gauge_length), float(noise_std), float(resolution), int(seed))
        for name, value in (("servo_bandwidth", servo_hz), ("servo_plant_gain", servo_g)):
            if not (float(value) >= 0 and math.isfinite(float(value))):
                raise PiezoParameterError(f"parameter {name} of {self.instance_name!r} is "
                                          f"{value!r}; expected >= 0 and finite")
        return PiezoActuator(self._stack, amp, gauge, bw,
                             float(stroke_limit) if stroke_limit > 0 else math.inf,
                             float(servo_hz), float(servo_g))

    def _coupling(self) -> int:
        c, h = int(self.coupling), float(self.hold_step)
        if c not in (0, 1):
            raise PiezoParameterError(f"parameter coupling of {self.instance_name!r} is {c}; "
                                      "expected 1 (mean force over the step) or 0 (force at "
                                      "the end of the last step)")
        if c == 1 and not (h > 0 and math.isfinite(h)):
            raise PiezoParameterError(f"parameter hold_step of {self.instance_name!r} is "
                                      f"{h!r}; expected the FMU's communication step (s)")
        return c

    def _step_ahead(self, dt: float):
        """The coming step with ``v_cmd`` held: ``(state, outputs, mean force)``, cached."""
        key = (self.x.tobytes(), float(self.v_cmd), float(self.elongation), float(dt),
               self._parameter_key())
        if self._ahead is None or self._ahead[0] != key:
            state, out, mean = ac.step_mean(self.actuator(), ActuatorState.from_array(self.x),
                                            self.v_cmd, dt, self.elongation)
            self._ahead = (key, state, out, mean)
        return self._ahead[1:]

    def _write_force(self) -> None:
        """Force held over the coming step (coupling 1) or the state's force (0)."""
        if self._coupling() == 1:
            self.force = self._step_ahead(float(self.hold_step))[2]
        else:
            self.force = ac.outputs(self.actuator(), ActuatorState.from_array(self.x)).force

    # ---------------------------------------------------------------- outputs
    def _write_outputs(self, out: ac.ActuatorOutputs) -> None:
        self.voltage = out.voltage
        self.current = out.current
        self.free_stroke = out.free_stroke
        self.sat_voltage = float(out.sat_voltage)
        self.sat_slew = float(out.sat_slew)
        self.sat_stroke = float(out.sat_stroke)

    def _write_strain(self) -> None:
        act = self.actuator()
        self.strain = ac.strain(act, ActuatorState.from_array(self.x), self.elongation)

    def set_real(self, vrs, values):
        """Set Real variables; once initialised, recompute the strain.

        Parameters
        ----------
        vrs : list of int
            Value references.
        values : list of float
            Values, one per reference, in each variable's unit (``v_cmd`` in V,
            ``elongation`` in m).
        """
        super().set_real(vrs, values)
        if self._ready:
            self._write_strain()
            self._force_stale = True

    def get_real(self, vrs):
        """Get Real variables (``fmi2GetReal``); the force is brought up to date first
        (computed when read, so a master that sets ``v_cmd`` after a step pays for one
        mean, not two).

        Parameters
        ----------
        vrs : list of int
            Value references.

        Returns
        -------
        list of float
        """
        if self._force_stale:
            self._write_force()
            self._force_stale = False
        return super().get_real(vrs)

    def _get_fmu_state(self):
        if self._force_stale:
            self._write_force()
            self._force_stale = False
        return super()._get_fmu_state()

    def _fmu_state_restored(self):
        ActuatorState.from_array(self.x)   # a valid actuator state, or StateArrayError
        if not {float(self.x[2]), float(self.x[3])} <= {0.0, 1.0}:
            raise PiezoParameterError(f"saturation flags {self.x[2:4].tolist()} of the "
                                      "actuator state are not 0 or 1")
        self._key = None  # parameters may have changed with the state
        self._ahead = None
        self._force_stale = False   # the state holds the force it was saved with

    # ---------------------------------------------------------------- FMI
    def exit_initialization_mode(self):
        act = self.actuator()
        state = ac.initial_state(act)
        self.x[...] = state.to_array()
        self._write_outputs(ac.outputs(act, state))
        self._ready = True
        self._write_strain()
        self._write_force()

    def do_step(self, current_time, step_size):
        """Advance the actuator with ``v_cmd`` held; write the outputs.

        Parameters
        ----------
        current_time : float
            Communication point at the start of the step (s): where the host's rounding of
            the step is judged.
        step_size : float
            Step (s), cut into the amplifier's internal sub-steps; with ``coupling = 1``
            it must be ``hold_step`` (to rounding), the step the force was the mean of.

        Returns
        -------
        bool
            Always True.
        """
        act = self.actuator()
        if self._coupling() == 1:
            h = float(self.hold_step)
            if not same_step(step_size, h, current_time + step_size):   # the host's rounding
                raise PiezoParameterError(
                    f"{self.instance_name!r} was stepped by {step_size!r} s, but its force "
                    f"is the mean over hold_step = {h!r} s; set hold_step to the "
                    "communication step (or coupling = 0)")
            state, out, _ = self._step_ahead(h)
        else:
            state, out = ac.step(act, ActuatorState.from_array(self.x), self.v_cmd, step_size,
                                 self.elongation)
        self.x[...] = state.to_array()
        self._write_outputs(out)
        self.strain = ac.strain(act, state, self.elongation)
        self._force_stale = True
        return True

