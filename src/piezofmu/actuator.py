"""Piezo actuator = stack + amplifier + optional hysteresis, stroke limit and strain gauge.

Signal chain of one step (pure functions on frozen dataclasses, SI units)::

    v_cmd --amplifier (bandwidth, slew, rails)--> v --Bouc-Wen (optional)--> v_eff = v - h
    v_eff --stroke limit (optional)--> f_c = c h v_eff                          (Eq. 1)

With ``servo_bandwidth > 0`` the stack's built-in servo loop is on: a strain gauge on the
stack measures its expansion (the ``elongation`` input, m), and an integrator drives the
amplifier (inside the loop) with ``dz/dt = k_i (d0 / V0 * v_cmd - elongation)``, so that
``v_cmd`` commands an expansion ``d0 / V0 * v_cmd`` instead of a voltage.  ``k_i = 2 pi
servo_bandwidth / servo_plant_gain`` (V/(m s)) sets the loop's crossover at
``servo_bandwidth`` for a mount whose expansion per volt at low frequency is
``servo_plant_gain`` (m/V; the free stroke per volt ``d0 / V0`` when 0).  The integrator
moves every internal sub-step with the elongation held over the caller step, clipped to
the rails (anti-windup); `linear_map` gives the same step as a linear map.

``f_c`` (N) is the force the active member applies to the structure: positive voltage
extends the stack and pushes its two end nodes apart.  The stroke limit clips the free
stroke ``d0 / V0 * v_eff`` to ``+-stroke_limit``.

The strain gauge reads the active-member elongation ``e`` (an input, m) as
``e / gauge_length`` plus seeded Gaussian noise, then quantises it.  The noise of a reading is
a function of ``(seed, tick)`` only (`gaussian`, counter-based), where ``tick`` counts
internal sub-steps since the start: it is reproducible, independent of how the caller splits
time, and needs no random generator in the saved state.

The force the structure holds over a communication step is either the force at the end
of the previous step (`step`, the ``coupling = 0`` of the FMU: a command then reaches the
structure one whole step late, which no hardware does) or the mean force over the coming
step with the command held (`step_mean`, ``coupling = 1``, the default): the trapezoidal
mean of the force at the internal sub-step ends, limits and hysteresis included.  With
the amplifier linear, that mean is the exact impulse the amplifier delivers over the step,
so a structure that holds it sees the command after the amplifier's own lag (about 80 us
for the 2 kHz P-865.10), not after a step.  That output has direct feedthrough from
``v_cmd``; the other outputs are functions of the state alone, and the strain has direct
feedthrough from the elongation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from piezofmu import amplifier as amp_mod
from piezofmu import hysteresis as hyst_mod
from piezofmu.amplifier import Amplifier, AmplifierState, amplifier_preset
from piezofmu.hysteresis import BoucWen
from piezofmu.stack import PiezoStack, preset
from fmukit.units import INCH

__all__ = [
    "ACTUATORS",
    "DEFAULT_BOUC_WEN",
    "ActuatorOutputs",
    "ActuatorState",
    "PiezoActuator",
    "StateArrayError",
    "StrainGauge",
    "actuator_preset",
    "gaussian",
    "initial_state",
    "inner_rows",
    "linear_map",
    "outputs",
    "step",
    "step_mean",
    "strain",
]


class StateArrayError(ValueError):
    """A state array has the wrong shape or content."""


@dataclass(frozen=True)
class StrainGauge:
    """Strain gauge in series with the active member.

    Parameters
    ----------
    length : float
        Gauge length ``L_g`` (m): strain = elongation / ``L_g``.
    noise_std : float
        Standard deviation of additive Gaussian noise (strain, -); 0 disables noise.
    resolution : float
        Quantisation step (strain, -); 0 disables quantisation.
    seed : int
        Seed of the noise, a non-negative integer.
    """

    length: float
    noise_std: float = 0.0
    resolution: float = 0.0
    seed: int = 0

    def __post_init__(self):
        if not (self.length > 0 and math.isfinite(self.length)):
            raise ValueError(f"strain gauge length must be positive and finite, got {self.length!r}")
        for name in ("noise_std", "resolution"):
            value = getattr(self, name)
            if not (value >= 0 and math.isfinite(value)):
                raise ValueError(f"strain gauge {name} must be >= 0 and finite, got {value!r}")
        if not (isinstance(self.seed, (int, np.integer)) and self.seed >= 0):
            raise ValueError(f"strain gauge seed must be a non-negative integer, got {self.seed!r}")

    def replace(self, **changes) -> "StrainGauge":
        """Copy with some fields changed."""
        return replace(self, **changes)


@dataclass(frozen=True)
class PiezoActuator:
    """A piezo stack driven by an amplifier.

    Parameters
    ----------
    stack : PiezoStack
        Stack datasheet model; gives ``c h`` (N/V), ``d0 / V0`` (m/V) and the capacitance (F).
    amplifier : Amplifier
        Amplifier model.
    gauge : StrainGauge
        Strain gauge of the active member.
    hysteresis : BoucWen or None
        Bouc–Wen hysteresis between applied voltage and free stroke; ``None`` disables it.
    stroke_limit : float
        Largest free-stroke magnitude (m); ``inf`` disables the limit.
    servo_bandwidth : float
        Crossover of the stack's built-in servo loop (Hz); 0: no servo, ``v_cmd`` drives
        the amplifier directly.
    servo_plant_gain : float
        Expansion per volt of the mounted stack at low frequency (m/V) that the servo's
        integrator is set for; 0: the free stroke per volt ``d0 / V0``.
    """

    stack: PiezoStack
    amplifier: Amplifier
    gauge: StrainGauge
    hysteresis: BoucWen | None = None
    stroke_limit: float = math.inf
    servo_bandwidth: float = 0.0
    servo_plant_gain: float = 0.0

    def __post_init__(self):
        if not self.stroke_limit > 0:
            raise ValueError(
                f"actuator {self.stack.name!r}: stroke_limit must be positive, "
                f"got {self.stroke_limit!r}"
            )
        for name, zero in (("servo_bandwidth", "no servo"), ("servo_plant_gain", "d0/V0")):
            value = getattr(self, name)
            if not (value >= 0 and math.isfinite(value)):
                raise ValueError(f"actuator {self.stack.name!r}: {name} must be >= 0 and "
                                 f"finite (0 for {zero}), got {value!r}")

    @property
    def servo_gain(self) -> float:
        """The servo integrator's gain ``k_i`` (V/(m s)); 0 with the servo off."""
        if self.servo_bandwidth == 0:
            return 0.0
        g = self.servo_plant_gain if self.servo_plant_gain > 0 else self.stroke_per_volt
        return 2.0 * math.pi * self.servo_bandwidth / g

    @property
    def stroke_per_volt(self) -> float:
        """Free stroke per volt ``d0 / V0`` (m/V)."""
        return self.stack.stroke / self.stack.rated_voltage

    def replace(self, **changes) -> "PiezoActuator":
        """Copy with some fields changed."""
        return replace(self, **changes)


@dataclass(frozen=True)
class ActuatorState:
    """Whole internal state of an actuator.

    Parameters
    ----------
    amp : AmplifierState
        Amplifier state (voltage, rate, saturation flags).
    h_bw : float
        Bouc–Wen state (V); 0 when hysteresis is off.
    tick : int
        Internal sub-steps taken since the start (keys the strain-gauge noise).
    z : float
        The servo integrator, the amplifier's command (V); 0 with the servo off.
    """

    amp: AmplifierState = field(default_factory=AmplifierState)
    h_bw: float = 0.0
    tick: int = 0
    z: float = 0.0

    #: Length of `to_array`.
    SIZE = 7

    def to_array(self) -> np.ndarray:
        """Pack into ``[v, dv/dt, sat_voltage, sat_slew, h_bw, tick, z]`` (float64,
        shape (7,))."""
        a = self.amp
        return np.array([a.voltage, a.rate, float(a.sat_voltage), float(a.sat_slew),
                         self.h_bw, float(self.tick), self.z])

    @classmethod
    def from_array(cls, array) -> "ActuatorState":
        """Unpack an array made by `to_array`."""
        x = np.asarray(array, dtype=float)
        if x.shape != (cls.SIZE,):
            raise StateArrayError(
                f"actuator state array has shape {x.shape}; expected ({cls.SIZE},)"
            )
        if not np.all(np.isfinite(x)) or x[5] < 0 or x[5] != round(x[5]):
            raise StateArrayError(f"actuator state array {x.tolist()} is not a valid state")
        return cls(AmplifierState(float(x[0]), float(x[1]), bool(x[2]), bool(x[3])),
                   float(x[4]), int(x[5]), float(x[6]))


@dataclass(frozen=True)
class ActuatorOutputs:
    """Outputs that depend on the state only.

    Parameters
    ----------
    force : float
        Actuator force on the structure ``f_c = c h v_eff`` (N).
    voltage : float
        Applied voltage ``v`` (V).
    current : float
        Amplifier current ``C dv/dt`` (A).
    free_stroke : float
        Free stroke ``d0 / V0 * v_eff`` after the stroke limit (m).
    sat_voltage, sat_slew, sat_stroke : bool
        Voltage rail, current (slew) and stroke limits active.
    """

    force: float
    voltage: float
    current: float
    free_stroke: float
    sat_voltage: bool
    sat_slew: bool
    sat_stroke: bool


def initial_state(act: PiezoActuator, voltage: float = 0.0) -> ActuatorState:
    """Return the actuator at rest at a voltage (V), with a virgin hysteresis state.

    Parameters
    ----------
    act : PiezoActuator
        Actuator model.
    voltage : float
        Initial applied voltage (V), clipped to the amplifier rails.

    Returns
    -------
    ActuatorState
        With zero voltage rate, Bouc–Wen state 0, tick 0 and the servo integrator at the
        voltage (0 with the servo off).
    """
    amp = amp_mod.initial_state(act.amplifier, voltage)
    return ActuatorState(amp, 0.0, 0, amp.voltage if act.servo_bandwidth > 0 else 0.0)


def outputs(act: PiezoActuator, state: ActuatorState) -> ActuatorOutputs:
    """Outputs of a state (force, voltage, current, free stroke, flags).

    Parameters
    ----------
    act : PiezoActuator
        Actuator model.
    state : ActuatorState
        The state.

    Returns
    -------
    ActuatorOutputs
        Force (N), voltage (V), current (A), free stroke (m) and saturation flags.
    """
    a = state.amp
    v_eff = a.voltage - state.h_bw
    stroke = act.stroke_per_volt * v_eff
    sat_stroke = abs(stroke) > act.stroke_limit
    if sat_stroke:
        stroke = math.copysign(act.stroke_limit, stroke)
        v_eff = stroke / act.stroke_per_volt
    return ActuatorOutputs(
        force=float(act.stack.force(v_eff)),
        voltage=a.voltage,
        current=act.stack.capacitance * a.rate,
        free_stroke=stroke,
        sat_voltage=a.sat_voltage,
        sat_slew=a.sat_slew,
        sat_stroke=bool(sat_stroke),
    )


def _servo_path(act, state, v_cmd, dt, elongation):
    """The amplifier's path over a step in the servo loop: ``(state, path, z)``."""
    if not math.isfinite(elongation):
        raise ValueError(f"actuator {act.stack.name!r}: elongation must be finite, "
                         f"got {elongation!r}")
    rate = act.servo_gain * (act.stroke_per_volt * float(v_cmd) - float(elongation))
    return amp_mod.servo_path(act.amplifier, act.stack.capacitance, state.amp, state.z,
                              rate, dt)


def step(act: PiezoActuator, state: ActuatorState, v_cmd: float,
         dt: float, elongation: float = 0.0) -> tuple[ActuatorState, ActuatorOutputs]:
    """Advance the actuator over one step with the voltage command held.

    Parameters
    ----------
    act : PiezoActuator
        Actuator model.
    state : ActuatorState
        State at the start of the step.
    v_cmd : float
        Voltage command (V), held over the step.
    dt : float
        Step size (s); see `piezofmu.amplifier` for the sub-stepping rule.
    elongation : float
        The stack's measured expansion (m), held over the step (the servo's feedback;
        unused with the servo off).

    Returns
    -------
    state : ActuatorState
        State at the end of the step.
    outputs : ActuatorOutputs
        Outputs at the end of the step.
    """
    n, _ = amp_mod.substeps(dt, act.amplifier.internal_step)
    cap = act.stack.capacitance
    z = state.z
    if act.servo_bandwidth > 0:
        amp_state, path, z = _servo_path(act, state, v_cmd, dt, elongation)
        h_bw = (state.h_bw if act.hysteresis is None else
                hyst_mod.step(act.hysteresis, state.h_bw, state.amp.voltage, path))
    elif act.hysteresis is None:
        amp_state, _ = amp_mod.step(act.amplifier, cap, state.amp, v_cmd, dt)
        h_bw = state.h_bw
    else:
        amp_state, path = amp_mod.step_path(act.amplifier, cap, state.amp, v_cmd, dt)
        h_bw = hyst_mod.step(act.hysteresis, state.h_bw, state.amp.voltage, path)
    new = ActuatorState(amp_state, h_bw, state.tick + n, z)
    return new, outputs(act, new)


def step_mean(act: PiezoActuator, state: ActuatorState, v_cmd: float,
              dt: float, elongation: float = 0.0
              ) -> tuple[ActuatorState, ActuatorOutputs, float]:
    """Advance like `step` and also return the mean force over the step (N).

    The mean is the trapezoidal rule on the force at the start and at every internal
    sub-step end (rails, slew limit, hysteresis and stroke limit included): with the
    amplifier linear it is the impulse the stack delivers over the step divided by
    ``dt``, to ``(w_c h)^2 / 12`` of the sub-step's change (1.3e-3 of it for the 2 kHz
    P-865.10 at 10 us).

    Parameters
    ----------
    act : PiezoActuator
        Actuator model.
    state : ActuatorState
        State at the start of the step.
    v_cmd : float
        Voltage command (V), held over the step.
    dt : float
        Step size (s); see `piezofmu.amplifier` for the sub-stepping rule.
    elongation : float
        The stack's measured expansion (m), held over the step (the servo's feedback;
        unused with the servo off).

    Returns
    -------
    state : ActuatorState
        State at the end of the step.
    outputs : ActuatorOutputs
        Outputs at the end of the step.
    mean_force : float
        Mean force over the step (N).
    """
    n, _ = amp_mod.substeps(dt, act.amplifier.internal_step)
    cap = act.stack.capacitance
    z = state.z
    if act.servo_bandwidth > 0:
        amp_state, path, z = _servo_path(act, state, v_cmd, dt, elongation)
    else:
        amp_state, path = amp_mod.step_path(act.amplifier, cap, state.amp, v_cmd, dt)
    ch, limit, bw = float(act.stack.ch), act.stroke_limit / act.stroke_per_volt, act.hysteresis
    h_bw, v_prev = state.h_bw, state.amp.voltage
    # summed in order, one sub-step at a time, as the native kernel does (bit for bit)
    f_prev = ch * min(max(v_prev - h_bw, -limit), limit)
    total = 0.0
    for v in path.tolist():
        if bw is not None:
            h_bw = hyst_mod.increment(bw, h_bw, v - v_prev)
        f = ch * min(max(v - h_bw, -limit), limit)
        total += 0.5 * (f_prev + f)
        f_prev, v_prev = f, v
    new = ActuatorState(amp_state, h_bw, state.tick + n, z)
    return new, outputs(act, new), total / n


def linear_map(act: PiezoActuator, dt: float):
    """One caller step of the actuator with no limit active, as a linear map.

    ``s+ = A s + B w`` with ``w = [v_cmd, elongation]`` held, composed of the internal
    sub-steps as `step_mean` takes them, on the amplifier's state (``[v]`` or ``[v,
    dv/dt]``) followed, with the servo on, by its integrator ``z``; and the trapezoidal
    mean of ``v`` over the sub-step ends, ``cx @ s + cu @ w``.

    Parameters
    ----------
    act : PiezoActuator
        Actuator model (its hysteresis is ignored).
    dt : float
        Step size (s).

    Returns
    -------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, 2)
    cx : ndarray, shape (n,)
    cu : ndarray, shape (2,)
    """
    return amp_mod.compose(*_sub_step(act, dt)[:3])


def _sub_step(act: PiezoActuator, dt: float):
    """One internal sub-step of a step ``dt`` with no limit active, ``s+ = As s + Bs w``
    (the state and inputs of `linear_map`), the number of sub-steps and their size."""
    amp = act.amplifier
    n_sub, h = amp_mod.substeps(dt, amp.internal_step)
    As, Bs = amp_mod.sub_step_map(amp, h)
    m = As.shape[0]
    if act.servo_bandwidth == 0:
        return As, np.hstack([Bs, np.zeros((m, 1))]), n_sub, h
    kd = h * act.servo_gain * np.array([[act.stroke_per_volt, -1.0]])   # dz = kd @ w
    Asub = np.block([[As, Bs], [np.zeros((1, m)), np.ones((1, 1))]])
    Bsub = np.vstack([0.5 * Bs @ kd, kd])   # the amplifier follows z + dz / 2
    return Asub, Bsub, n_sub, h


def inner_rows(act: PiezoActuator, dt: float) -> dict:
    """The limited values at every internal sub-step of a step with no limit active, as
    linear maps of the state at the step's start and the inputs held over it.

    The amplifier's rails and current limit act at each sub-step (`step`): a limit can be
    reached inside a step and released before its end.  Row ``j`` gives, from ``[s, w]``
    (``s`` the state of `linear_map` at the step's start, ``w = [v_cmd, elongation]``),
    the value at sub-step ``j``: the voltage ``v_j``; the current ``C (v_j - v_(j-1)) /
    h`` that the slew limit clips (``|dv| <= S h``) and, for order 2, ``C r_j`` (the rate
    state it clips).

    Parameters
    ----------
    act : PiezoActuator
        The actuator (its hysteresis is ignored).
    dt : float
        The step (s).

    Returns
    -------
    dict
        ``"voltage"`` (n_sub, m + 2) in V and ``"current"`` (n_sub or 2 n_sub, m + 2) in
        A, ``m`` the state's size.
    """
    As, Bs, n, h = _sub_step(act, dt)
    m = As.shape[0]
    S = np.zeros((n + 1, m, m + 2))     # s_j = S[j] @ [s_start, w], j = 0 .. n
    S[0, :, :m] = np.eye(m)
    for j in range(n):
        S[j + 1] = As @ S[j]
        S[j + 1, :, m:] += Bs
    v = S[:, 0]
    cap = act.stack.capacitance
    current = [cap * np.diff(v, axis=0) / h]
    if act.amplifier.order == 2:
        current.append(cap * S[1:, 1])
    return {"voltage": v[1:], "current": np.vstack(current)}


_MASK64 = (1 << 64) - 1


def _splitmix64(x: int) -> int:
    """SplitMix64 finaliser of ``x + golden gamma`` (Steele, Lea & Flood 2014)."""
    z = (x + 0x9E3779B97F4A7C15) & _MASK64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK64
    return z ^ (z >> 31)


def gaussian(seed: int, counter: int) -> float:
    """Standard normal sample that is a pure function of ``(seed, counter)``.

    Counter-based: two SplitMix64 hashes give two uniforms, Box–Muller gives the sample.
    Pure Python integers, so the sequence is the same on every platform and numpy version.

    Parameters
    ----------
    seed : int
        Non-negative seed.
    counter : int
        Non-negative sample index.

    Returns
    -------
    float
        Sample of N(0, 1).
    """
    h1 = _splitmix64(_splitmix64(int(seed) & _MASK64) ^ (int(counter) & _MASK64))
    h2 = _splitmix64(h1)
    u1 = ((h1 >> 11) + 1) * 2.0**-53  # (0, 1]
    u2 = (h2 >> 11) * 2.0**-53  # [0, 1)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


def strain(act: PiezoActuator, state: ActuatorState, elongation: float) -> float:
    """Strain-gauge reading for a member elongation (m), noise keyed by the state's tick (-).

    Parameters
    ----------
    act : PiezoActuator
        Actuator model (its gauge gives length, noise and resolution).
    state : ActuatorState
        Current state; its ``tick`` keys the noise sample.
    elongation : float
        Elongation of the active member (m).

    Returns
    -------
    float
        Strain reading (-): ``elongation / length`` plus noise, quantised.
    """
    g = act.gauge
    eps = float(elongation) / g.length
    if g.noise_std > 0.0:
        eps += g.noise_std * gaussian(g.seed, state.tick)
    if g.resolution > 0.0:
        eps = g.resolution * round(eps / g.resolution)
    return eps


#: Default Bouc-Wen shape ``(alpha, beta V0, gamma V0)``, an assumption: the branch gap at
#: v = 0 is 10 % of the stroke span for a +-V0/2 sine (docs/piezo.md).
DEFAULT_BOUC_WEN = (0.25, 3.0, 1.0)


def _default_hysteresis(stack: PiezoStack) -> BoucWen:
    return BoucWen.scaled(*DEFAULT_BOUC_WEN, v0=stack.rated_voltage)


def _make(stack_name: str, amp_name: str, gauge_length: float) -> PiezoActuator:
    stack = preset(stack_name)
    return PiezoActuator(stack, amplifier_preset(amp_name), StrainGauge(gauge_length))


# Gauge lengths are assumptions: the truss member lengths of the 10 in bays for the longeron
# and the diagonal, the stack length for the isolator (gauge on the internal stack).
ACTUATORS: dict[str, PiezoActuator] = {
    "P-243.30": _make("P-243.30", "Trek 50/750", 10.0 * INCH),
    "P-243.40": _make("P-243.40", "Trek 50/750", 10.0 * math.sqrt(2.0) * INCH),
    "P-845.37": _make("P-845.37", "P-865.10", preset("P-845.37").length),
}


def actuator_preset(name: str, hysteresis: bool = False) -> PiezoActuator:
    """Return a preset actuator by stack model number, optionally with default hysteresis.

    Parameters
    ----------
    name : str
        ``"P-243.30"``, ``"P-243.40"`` or ``"P-845.37"`` (``"P243.30"`` also accepted).
    hysteresis : bool
        Attach the default Bouc–Wen model (an assumption, see docs/piezo.md).
    """
    key = preset(name).name
    act = ACTUATORS[key]
    if hysteresis:
        act = act.replace(hysteresis=_default_hysteresis(act.stack))
    return act
