"""Piezo amplifier: bandwidth, voltage rails and current (slew) limit (pure numerics, SI).

The amplifier output voltage ``v`` follows the command ``u`` through a low-pass of order
one or two,

    first order:   dv/dt = w_c (u - v)
    second order:  d2v/dt2 = w_c^2 (u - v) - 2 zeta w_c dv/dt,      w_c = 2 pi f_c

and two limits act on the output stage:

* the current limit ``|i| = C |dv/dt| <= I_max`` with ``C`` the load (stack) capacitance, i.e.
  a slew-rate limit ``|dv/dt| <= S = I_max / C``;
* the voltage rails ``v_min <= v <= v_max`` (clipping).

Time stepping rule
------------------
A caller step ``dt`` is cut into ``n`` internal sub-steps of the fixed size
``Amplifier.internal_step`` (``h``) when ``dt`` is an integer multiple of ``h`` (relative
tolerance 1e-9); the command is held over the caller step.  Each sub-step advances the linear
low-pass exactly (zero-order-hold discretisation, so a constant command gives the analytic
response to round-off), then applies the limits: the voltage increment is clipped to
``+-S h``, the rate state to ``+-S``, and the voltage to the rails (anti-windup: the clipped
values are the new state).  Because ``h`` is fixed, the response does not depend on how the
caller splits time: stepping 0.004 s once equals stepping 0.001 s four times to round-off.
When ``dt`` is not a multiple of ``h`` it is cut into ``n = ceil(dt / h)`` equal sub-steps of
``dt / n``; the linear part is still exact, only the instants at which the limits act move
(by less than ``h``).

The current reports the last internal sub-step of a call.  The saturation flags say whether
a limit acted at any internal sub-step of the call (set at the sub-step, kept to the call's
end, cleared at the next call's start): a limit reached and released inside one step is
reported by that step.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

__all__ = [
    "AMPLIFIERS",
    "Amplifier",
    "AmplifierOutputs",
    "AmplifierState",
    "amplifier_preset",
    "initial_state",
    "compose",
    "linear_map",
    "outputs",
    "servo_path",
    "step",
    "step_path",
    "sub_step_map",
    "substeps",
]

#: Relative tolerance for deciding that a caller step is a multiple of the internal step.
MULTIPLE_RTOL = 1e-9


class AmplifierError(ValueError):
    """Invalid amplifier parameters or inputs."""


@dataclass(frozen=True)
class Amplifier:
    """Voltage amplifier driving a capacitive (piezo stack) load.

    Parameters
    ----------
    name : str
        Model name, e.g. ``"Trek 50/750"``.
    v_min, v_max : float
        Output voltage rails (V); ``v_min < v_max``.  ``-inf``/``inf`` disable clipping.
    i_max : float
        Output current limit (A); ``inf`` disables the slew limit.
    bandwidth : float
        Cut-off (first order) or natural (second order) frequency ``f_c`` (Hz).
    order : int
        Order of the low-pass, 1 or 2.
    damping : float
        Damping ratio ``zeta`` of the second-order low-pass (-); unused for order 1.
    internal_step : float
        Fixed internal sub-step ``h`` (s).
    """

    name: str = "amplifier"
    v_min: float = -math.inf
    v_max: float = math.inf
    i_max: float = math.inf
    bandwidth: float = 1000.0
    order: int = 1
    damping: float = math.sqrt(0.5)
    internal_step: float = 1e-5

    def __post_init__(self):
        if self.order not in (1, 2):
            raise AmplifierError(f"amplifier {self.name!r}: order must be 1 or 2, got {self.order!r}")
        for field in ("bandwidth", "damping", "internal_step", "i_max"):
            value = getattr(self, field)
            finite_ok = field == "i_max"
            if not (value > 0 and (finite_ok or math.isfinite(value))):
                raise AmplifierError(
                    f"amplifier {self.name!r}: {field} must be a positive finite number, "
                    f"got {value!r}"
                )
        if not self.v_min < self.v_max:
            raise AmplifierError(
                f"amplifier {self.name!r}: v_min must be below v_max, got v_min={self.v_min!r}, "
                f"v_max={self.v_max!r}"
            )

    @property
    def omega(self) -> float:
        """Angular cut-off / natural frequency ``2 pi f_c`` (rad/s)."""
        return 2.0 * math.pi * self.bandwidth

    def slew_rate(self, capacitance: float) -> float:
        """Slew-rate limit ``S = I_max / C`` (V/s) for a load capacitance (F)."""
        return self.i_max / capacitance

    def replace(self, **changes) -> "Amplifier":
        """Copy with some fields changed."""
        return replace(self, **changes)


@dataclass(frozen=True)
class AmplifierState:
    """State of an amplifier at the end of a step.

    Parameters
    ----------
    voltage : float
        Output voltage ``v`` (V).
    rate : float
        Output voltage rate ``dv/dt`` (V/s): a state for order 2, the rate at the end of the
        last sub-step (with its command) for order 1.
    sat_voltage : bool
        A rail clipped the output at some internal sub-step of the last step.
    sat_slew : bool
        The current (slew) limit was active at some internal sub-step of the last step.
    """

    voltage: float = 0.0
    rate: float = 0.0
    sat_voltage: bool = False
    sat_slew: bool = False


@dataclass(frozen=True)
class AmplifierOutputs:
    """Amplifier outputs at the end of a step.

    Parameters
    ----------
    voltage : float
        Output voltage (V).
    current : float
        Output current ``C dv/dt`` (A).
    sat_voltage, sat_slew : bool
        Saturation flags (see `AmplifierState`).
    """

    voltage: float
    current: float
    sat_voltage: bool
    sat_slew: bool


def initial_state(amp: Amplifier, voltage: float = 0.0) -> AmplifierState:
    """Return the amplifier at rest at a voltage (V), clipped to the rails.

    Parameters
    ----------
    amp : Amplifier
        Amplifier parameters.
    voltage : float
        Initial output voltage (V).

    Returns
    -------
    AmplifierState
        Zero rate; ``sat_voltage`` set when the voltage was clipped.
    """
    v = min(max(float(voltage), amp.v_min), amp.v_max)
    return AmplifierState(voltage=v, rate=0.0, sat_voltage=v != voltage, sat_slew=False)


def substeps(dt: float, h: float) -> tuple[int, float]:
    """Split a caller step into internal sub-steps.

    Parameters
    ----------
    dt : float
        Caller step (s), ``dt > 0``.
    h : float
        Internal step (s).

    Returns
    -------
    n : int
        Number of sub-steps.
    size : float
        Sub-step size (s): exactly ``h`` when ``dt`` is a multiple of ``h``, else ``dt / n``.
    """
    if not (dt > 0 and math.isfinite(dt)):
        raise AmplifierError(f"step size dt must be a positive finite number, got {dt!r}")
    ratio = dt / h
    n = round(ratio)
    if n >= 1 and abs(ratio - n) <= MULTIPLE_RTOL * ratio:
        return n, h
    n = math.ceil(ratio)
    return n, dt / n


def _expm(a: np.ndarray) -> np.ndarray:
    """Matrix exponential by scaling and squaring of a Taylor series (small matrices)."""
    norm = float(np.max(np.sum(np.abs(a), axis=1)))
    squarings = max(0, math.ceil(math.log2(norm / 0.25))) if norm > 0.25 else 0
    x = a / 2.0**squarings
    term = np.eye(a.shape[0])
    out = term.copy()
    for k in range(1, 19):  # |x| <= 1/4: the remainder is below 0.25^19 / 19! ~ 1e-28
        term = term @ x / k
        out = out + term
    for _ in range(squarings):
        out = out @ out
    return out


@functools.lru_cache(maxsize=128)
def _coefficients(amp: Amplifier, h: float) -> tuple[float, ...]:
    """Zero-order-hold coefficients of the low-pass over one sub-step ``h`` (s)."""
    w = amp.omega
    if amp.order == 1:
        return (math.exp(-w * h),)
    z = amp.damping
    # in the scaled state (v, r / w) every entry is of order w h, so the Taylor series
    # keeps full relative accuracy (on (v, r) the entries span w^2 h to h, and the
    # small ones lose about 1e-12 at w h = 0.1, 1e-7 at w h = 10)
    wh = w * h
    e = _expm(wh * np.array([[0.0, 1.0, 0.0], [-1.0, -2.0 * z, 1.0], [0.0, 0.0, 0.0]]))
    # [v, r]_{k+1} = [[a11, a12], [a21, a22]] [v, r]_k + [b1, b2] u
    return tuple(float(x) for x in (e[0, 0], e[0, 1] / w, e[1, 0] * w, e[1, 1], e[0, 2],
                                    e[1, 2] * w))


def _advance(amp: Amplifier, capacitance: float, state: AmplifierState, v_cmd: float,
             dt: float, path: list | None, servo: list | None = None) -> AmplifierState:
    """The sub-steps of one caller step.  With ``servo = [z, rate]`` the command is not
    ``v_cmd`` but a servo integrator ``z`` (V) rising by ``rate`` (V/s) held over the step:
    each sub-step ``z+ = clip(z + h rate)`` (clipped to the rails: anti-windup) and the
    amplifier follows the sub-step's mean ``(z + z+) / 2``; ``servo[0]`` ends as the
    final ``z``."""
    if not (capacitance > 0 and math.isfinite(capacitance)):
        raise AmplifierError(
            f"amplifier {amp.name!r}: load capacitance must be positive and finite, "
            f"got {capacitance!r}"
        )
    if not math.isfinite(v_cmd):
        raise AmplifierError(f"amplifier {amp.name!r}: command v_cmd must be finite, got {v_cmd!r}")
    n, h = substeps(dt, amp.internal_step)
    coef = _coefficients(amp, h)
    s_max = amp.slew_rate(capacitance)
    dv_max = s_max * h
    v_lo, v_hi = amp.v_min, amp.v_max
    v, r = float(state.voltage), float(state.rate)
    u = float(v_cmd)
    sat_v = sat_s = False
    any_v = any_s = False   # a limit that acted at any sub-step of this step
    first = amp.order == 1
    if first:
        (a,) = coef
        w = amp.omega
    else:
        a11, a12, a21, a22, b1, b2 = coef
    if servo is not None:
        z, dz = servo[0], h * servo[1]
    for _ in range(n):
        if servo is not None:
            z_new = min(max(z + dz, v_lo), v_hi)
            u = 0.5 * (z + z_new)
            z = z_new
        if first:
            v_new = u + (v - u) * a
            r_new = 0.0  # set below
        else:
            v_new = a11 * v + a12 * r + b1 * u
            r_new = a21 * v + a22 * r + b2 * u
        dv = v_new - v
        sat_s = False
        if dv > dv_max:
            v_new, sat_s = v + dv_max, True
        elif dv < -dv_max:
            v_new, sat_s = v - dv_max, True
        if first:
            r_new = w * (u - v_new)
        if r_new > s_max:
            r_new, sat_s = s_max, sat_s or not first
        elif r_new < -s_max:
            r_new, sat_s = -s_max, sat_s or not first
        sat_v = False
        if v_new > v_hi:
            v_new, sat_v = v_hi, True
            r_new = min(r_new, 0.0)
        elif v_new < v_lo:
            v_new, sat_v = v_lo, True
            r_new = max(r_new, 0.0)
        elif first and ((v_new == v_hi and r_new > 0) or (v_new == v_lo and r_new < 0)):
            r_new, sat_v = 0.0, True
        any_v, any_s = any_v or sat_v, any_s or sat_s
        v, r = v_new, r_new
        if path is not None:
            path.append(v)
    if servo is not None:
        servo[0] = z
    return AmplifierState(voltage=v, rate=r, sat_voltage=any_v, sat_slew=any_s)


def outputs(amp: Amplifier, capacitance: float, state: AmplifierState) -> AmplifierOutputs:
    """Amplifier outputs of a state; the current is ``C dv/dt`` (A).

    Parameters
    ----------
    amp : Amplifier
        Amplifier parameters.
    capacitance : float
        Load capacitance ``C`` (F).
    state : AmplifierState
        The state.

    Returns
    -------
    AmplifierOutputs
    """
    return AmplifierOutputs(voltage=state.voltage, current=capacitance * state.rate,
                            sat_voltage=state.sat_voltage, sat_slew=state.sat_slew)


def step(amp: Amplifier, capacitance: float, state: AmplifierState, v_cmd: float,
         dt: float) -> tuple[AmplifierState, AmplifierOutputs]:
    """Advance the amplifier over one caller step with the command held.

    Parameters
    ----------
    amp : Amplifier
        Amplifier parameters.
    capacitance : float
        Load capacitance ``C`` (F).
    state : AmplifierState
        State at the start of the step.
    v_cmd : float
        Voltage command, held over the step (V).
    dt : float
        Step size (s).

    Returns
    -------
    state : AmplifierState
        State at the end of the step.
    outputs : AmplifierOutputs
        Outputs at the end of the step.
    """
    new = _advance(amp, capacitance, state, v_cmd, dt, None)
    return new, outputs(amp, capacitance, new)


def step_path(amp: Amplifier, capacitance: float, state: AmplifierState, v_cmd: float,
              dt: float) -> tuple[AmplifierState, np.ndarray]:
    """Advance like `step` and also return the voltage at every sub-step end.

    Parameters
    ----------
    amp : Amplifier
        Amplifier parameters.
    capacitance : float
        Load capacitance ``C`` (F).
    state : AmplifierState
        State at the start of the step.
    v_cmd : float
        Voltage command, held over the step (V).
    dt : float
        Step size (s).

    Returns
    -------
    state : AmplifierState
        State at the end of the step.
    path : numpy.ndarray, shape (n,)
        Output voltage at the end of each internal sub-step (V); ``path[-1]`` is the final
        voltage.
    """
    path: list[float] = []
    new = _advance(amp, capacitance, state, v_cmd, dt, path)
    return new, np.asarray(path)


def servo_path(amp: Amplifier, capacitance: float, state: AmplifierState, z: float,
               rate: float, dt: float) -> tuple[AmplifierState, np.ndarray, float]:
    """Advance like `step_path` with the command a servo integrator (V).

    Each internal sub-step of size ``h`` the integrator moves ``z+ = z + h rate``,
    clipped to the rails (anti-windup), and the amplifier follows the sub-step's mean
    ``(z + z+) / 2`` (the exact mean of the unclipped ramp).

    Parameters
    ----------
    amp : Amplifier
        Amplifier parameters.
    capacitance : float
        Load capacitance ``C`` (F).
    state : AmplifierState
        State at the start of the step.
    z : float
        Integrator (the amplifier's command) at the start of the step (V).
    rate : float
        The integrator's rate, held over the step (V/s).
    dt : float
        Step size (s).

    Returns
    -------
    state : AmplifierState
        State at the end of the step.
    path : numpy.ndarray, shape (n,)
        Output voltage at the end of each internal sub-step (V).
    z : float
        Integrator at the end of the step (V).
    """
    if not math.isfinite(rate):
        raise AmplifierError(f"amplifier {amp.name!r}: servo rate must be finite, got {rate!r}")
    path: list[float] = []
    servo = [float(z), float(rate)]
    new = _advance(amp, capacitance, state, 0.0, dt, path, servo)
    return new, np.asarray(path), servo[0]


def sub_step_map(amp: Amplifier, h: float) -> tuple[np.ndarray, np.ndarray]:
    """One internal sub-step ``h`` (s) with no limit active: ``s+ = As s + Bs u``.

    Parameters
    ----------
    amp : Amplifier
        Amplifier parameters.
    h : float
        Sub-step (s).

    Returns
    -------
    As : ndarray, shape (m, m)
        On the state ``[v]`` (order 1) or ``[v, dv/dt]`` (order 2).
    Bs : ndarray, shape (m, 1)
    """
    coef = _coefficients(amp, h)
    if amp.order == 1:
        return np.array([[coef[0]]]), np.array([[1.0 - coef[0]]])
    a11, a12, a21, a22, b1, b2 = coef
    return np.array([[a11, a12], [a21, a22]]), np.array([[b1], [b2]])


def compose(As: np.ndarray, Bs: np.ndarray, n_sub: int):
    """``n_sub`` sub-steps ``s+ = As s + Bs u`` with ``u`` held, and the trapezoidal mean
    of the first state over the sub-step ends.

    Parameters
    ----------
    As : ndarray, shape (m, m)
    Bs : ndarray, shape (m, k)
    n_sub : int
        Number of sub-steps.

    Returns
    -------
    A : ndarray, shape (m, m)
    B : ndarray, shape (m, k)
    cx : ndarray, shape (m,)
    cu : ndarray, shape (k,)
        The mean of ``s[0]`` is ``cx @ s + cu @ u``.
    """
    m = As.shape[0]
    A, B = np.eye(m), np.zeros_like(Bs, dtype=float)
    cx, cu = np.zeros(m), np.zeros(Bs.shape[1])
    for _ in range(n_sub):
        An, Bn = As @ A, As @ B + Bs
        cx += 0.5 * (A[0] + An[0])
        cu += 0.5 * (B[0] + Bn[0])
        A, B = An, Bn
    return A, B, cx / n_sub, cu / n_sub


def linear_map(amp: Amplifier, dt: float):
    """One caller step of the amplifier with no limit active, as a linear map.

    ``s+ = A s + B u`` on the state ``s = [v]`` (order 1) or ``[v, dv/dt]`` (order 2)
    with the command ``u`` held, composed of the internal sub-steps exactly as `step`
    takes them; and the trapezoidal mean of ``v`` over the sub-step ends (what
    ``piezofmu.actuator.step_mean`` averages), ``mean = cx @ s + cu u``.

    Parameters
    ----------
    amp : Amplifier
        Amplifier parameters.
    dt : float
        Step size (s).

    Returns
    -------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, 1)
    cx : ndarray, shape (n,)
    cu : float
    """
    n_sub, h = substeps(dt, amp.internal_step)
    A, B, cx, cu = compose(*sub_step_map(amp, h), n_sub)
    return A, B, cx, float(cu[0])


# Amplifier presets.  Voltage and current limits are from the paper (see docs/piezo.md);
# bandwidths, orders, damping and internal steps are assumptions.
AMPLIFIERS: dict[str, Amplifier] = {
    # Trek 50/750: "up to 1500 V", 50 mA average current.
    "Trek 50/750": Amplifier("Trek 50/750", v_min=-1500.0, v_max=1500.0, i_max=50e-3,
                             bandwidth=500.0, order=2, damping=0.6, internal_step=1e-5),
    # PI P-865.10: up to 100 V and 30 W per channel, operated at +-50 V; I_max = 30 W / 100 V.
    "P-865.10": Amplifier("P-865.10", v_min=-50.0, v_max=50.0, i_max=0.3,
                          bandwidth=2000.0, order=1, internal_step=1e-5),
}


def amplifier_preset(name: str) -> Amplifier:
    """Return a preset amplifier by name (``"Trek 50/750"`` or ``"P-865.10"``)."""
    if name not in AMPLIFIERS:
        raise KeyError(f"unknown amplifier {name!r}; known: {', '.join(AMPLIFIERS)}")
    return AMPLIFIERS[name]
