"""Discrete three-axis PID attitude control with reaction wheels (pure numerics, SI).

Control law, per body axis ``i``, sampled every ``T`` seconds at ``t_n = n T``::

    theta_n, omega_n = F_aa(sampled inputs)            (optional anti-alias biquads)
    e_n  = theta_n - theta_ref
    v_n  = -(kp e_n + kd (omega_n - 0) + ki z_n)      (commanded torque, N m)
    w_n  = F_lp(F_notch(v_n))                         (optional notch, then low-pass)
    u_n  = sat(w_n)                                   (torque and momentum limits)
    z_{n+1} = z_n + T e_n   unless the integration drives further into saturation

* Filters (:mod:`acsfmu.filters`): second-order sections discretised by Tustin
  prewarped at their corner, direct form II transposed, states advanced once per
  sample; all off by default, and then the law is exactly the unfiltered one.  The
  anti-alias filter works on the samples at the controller's rate: it cannot remove
  what aliased before sampling.

* Discretisation: the integral is forward Euler (rectangle rule on the sample at
  ``t_n``); the derivative term uses the measured body rate (rate gyro) on the same
  sample, so no numerical differentiation and no derivative kick.
* One-sample computational delay: ``u_n`` is applied from ``t_{n+1}`` to ``t_{n+2}``
  (zero-order hold).  The torque output at any instant therefore depends only on past
  samples: there is no direct feedthrough from attitude or rate to torque, and a
  master sees no algebraic loop.  The delay costs ``omega_c T`` rad of phase margin
  (2.2 deg at 0.1 Hz and 10 Hz); :func:`acsfmu.design.design_pid` compensates it.
* Wheels: one wheel per body axis; the torque on the body is ``u``, so the wheel
  momentum obeys ``dh/dt = -u`` and the wheel speed is ``h / J_wheel``.
* Saturation: ``|u| <= torque_limit``, and ``u`` is clipped so that the predicted
  wheel momentum at the end of its application interval stays within
  ``+-momentum_limit`` (the torque limit wins if the two conflict).
* Anti-windup by conditional integration: the integrator is frozen on an axis when the
  torque is saturated (``u_n != w_n``) and the new error would push the command further
  past the limit.

Time is handled by integer sample indices: :func:`acs_advance` processes every sample
``n T`` in ``[t, t + h)`` with the inputs held, so the result is the same whether a
master calls it once per sample or with larger or smaller steps (sub-stepping).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from acsfmu.filters import AcsConfigError, AcsFilters, biquad_step, per_axis as _vec3

__all__ = ["AcsConfig", "AcsConfigError", "AcsFilters", "AcsState", "PidGains", "acs_advance",
           "acs_outputs", "initial_state", "pid_command"]

@dataclass(frozen=True, eq=False)
class PidGains:
    """Parallel PID gains per body axis.

    Parameters
    ----------
    kp : array_like, shape (3,)
        Proportional gains (N m/rad).
    ki : array_like, shape (3,)
        Integral gains (N m/(rad s)).
    kd : array_like, shape (3,)
        Rate gains (N m s/rad).
    """

    kp: np.ndarray
    ki: np.ndarray
    kd: np.ndarray

    def __post_init__(self):
        for name in ("kp", "ki", "kd"):
            v = _vec3(getattr(self, name), "PID gains", name)
            if np.any(v < 0):
                raise AcsConfigError(f"PID gains: {name} must be non-negative, got {v}")
            object.__setattr__(self, name, v)


@dataclass(frozen=True, eq=False)
class AcsConfig:
    """Controller, sampling and wheel parameters.

    Parameters
    ----------
    gains : PidGains
        PID gains per axis.
    sample_time : float
        Controller period ``T`` (s).
    torque_limit : array_like, shape (3,) or scalar
        Wheel torque limit per axis (N m).
    momentum_limit : array_like, shape (3,) or scalar
        Wheel momentum limit per axis (N m s).
    wheel_inertia : array_like, shape (3,) or scalar
        Wheel rotor inertia per axis (kg m^2).
    reference : array_like, shape (3,) or scalar
        Attitude reference, roll, pitch, yaw (rad).
    anti_windup : bool
        Freeze the integrator while saturated (conditional integration).
    filters : AcsFilters, optional
        Notch, low-pass and anti-alias filters at ``sample_time``; None for none.
    """

    gains: PidGains
    sample_time: float = 0.1
    torque_limit: np.ndarray = 0.4
    momentum_limit: np.ndarray = 75.0
    wheel_inertia: np.ndarray = 0.2
    reference: np.ndarray = 0.0
    anti_windup: bool = True
    filters: AcsFilters | None = None

    def __post_init__(self):
        owner = "ACS config"
        if not (isinstance(self.sample_time, (int, float)) and math.isfinite(self.sample_time)
                and self.sample_time > 0):
            raise AcsConfigError(f"{owner}: sample_time must be a positive number, got "
                                 f"{self.sample_time!r}")
        if self.filters is None or (isinstance(self.filters, AcsFilters)
                                    and not self.filters.any_on):
            # no filter: the set is rebuilt at this sample time (a replace() may change it)
            object.__setattr__(self, "filters", AcsFilters(self.sample_time))
        elif not isinstance(self.filters, AcsFilters):
            raise AcsConfigError(f"{owner}: filters must be an AcsFilters, got "
                                 f"{type(self.filters).__name__}")
        elif self.filters.sample_time != self.sample_time:
            raise AcsConfigError(f"{owner}: filters run at {self.filters.sample_time!r} s but "
                                 f"the controller samples every {self.sample_time!r} s")
        for name, pos in (("torque_limit", True), ("momentum_limit", True),
                          ("wheel_inertia", True), ("reference", False)):
            object.__setattr__(self, name, _vec3(getattr(self, name), owner, name, pos))

    def replace(self, **changes) -> AcsConfig:
        """Copy with some fields changed."""
        return replace(self, **changes)


@dataclass(frozen=True, eq=False)
class AcsState:
    """Full internal state of the controller and wheels.

    Parameters
    ----------
    integral : ndarray, shape (3,)
        Integrator states ``z`` (rad s).
    torque_active : ndarray, shape (3,)
        Torque currently applied to the body (N m).
    torque_pending : ndarray, shape (3,)
        Torque computed at the last sample, applied from the next sample (N m).
    momentum : ndarray, shape (3,)
        Wheel angular momentum at ``time`` (N m s).
    next_sample : int
        Index ``n`` of the next sample to take (at ``n T``).
    activated : int
        Index of the last sample at which the pending torque became active.
    time : float
        Time of the state (s).
    antialias : ndarray, shape (6, 2)
        Input filter states ``(s1, s2)`` of roll, pitch, yaw, rate_x, rate_y, rate_z.
    notch : ndarray, shape (3, 2)
        Notch states per axis (N m).
    lowpass : ndarray, shape (3, 2)
        Torque low-pass states per axis (N m).
    """

    integral: np.ndarray = field(default_factory=lambda: np.zeros(3))
    torque_active: np.ndarray = field(default_factory=lambda: np.zeros(3))
    torque_pending: np.ndarray = field(default_factory=lambda: np.zeros(3))
    momentum: np.ndarray = field(default_factory=lambda: np.zeros(3))
    next_sample: int = 0
    activated: int = -1
    time: float = 0.0
    antialias: np.ndarray = field(default_factory=lambda: np.zeros((6, 2)))
    notch: np.ndarray = field(default_factory=lambda: np.zeros((3, 2)))
    lowpass: np.ndarray = field(default_factory=lambda: np.zeros((3, 2)))

    #: Length of :meth:`as_array`: 15 controller and wheel values, 24 filter states.
    SIZE = 39

    def as_array(self) -> np.ndarray:
        """Flatten to a float array of length 39 (for FMU state save/restore).

        Layout: integral (3), torque_active (3), torque_pending (3), momentum (3),
        next_sample, activated, time, then the filter states row by row: antialias
        (6 x 2), notch (3 x 2), lowpass (3 x 2).  The native kernel uses the same.
        """
        return np.concatenate([self.integral, self.torque_active, self.torque_pending,
                               self.momentum, [self.next_sample, self.activated, self.time],
                               np.ravel(self.antialias), np.ravel(self.notch),
                               np.ravel(self.lowpass)])

    @classmethod
    def from_array(cls, a) -> AcsState:
        """Inverse of :meth:`as_array`."""
        a = np.asarray(a, dtype=float)
        if a.shape != (cls.SIZE,):
            raise AcsConfigError(f"ACS state array has shape {a.shape}; expected "
                                 f"({cls.SIZE},)")
        return cls(a[0:3].copy(), a[3:6].copy(), a[6:9].copy(), a[9:12].copy(),
                   int(round(a[12])), int(round(a[13])), float(a[14]),
                   a[15:27].reshape(6, 2).copy(), a[27:33].reshape(3, 2).copy(),
                   a[33:39].reshape(3, 2).copy())


def initial_state(config: AcsConfig, t0: float = 0.0, momentum0=0.0) -> AcsState:
    """State at ``t0`` with zero torque and the given wheel momentum.

    Parameters
    ----------
    config : AcsConfig
        Controller parameters (for the sample time).
    t0 : float
        Start time (s).
    momentum0 : array_like, shape (3,) or scalar
        Initial wheel momentum (N m s).

    Returns
    -------
    AcsState
    """
    T = config.sample_time
    n0 = math.ceil(t0 / T - 1e-6)
    return AcsState(momentum=_vec3(momentum0, "ACS initial state", "momentum0").copy(),
                    next_sample=n0, activated=n0 - 1, time=float(t0))


def pid_command(config: AcsConfig, integral, attitude, rate, momentum_next, filters=None):
    """One sample of the control law: saturated torque, new integrator and filters.

    Parameters
    ----------
    config : AcsConfig
        Controller parameters.
    integral : ndarray, shape (3,)
        Integrator state ``z_n`` (rad s).
    attitude : ndarray, shape (3,)
        Sampled roll, pitch, yaw (rad).
    rate : ndarray, shape (3,)
        Sampled body rates (rad/s).
    momentum_next : ndarray, shape (3,)
        Predicted wheel momentum when the new torque becomes active (N m s).
    filters : tuple of ndarray, optional
        Filter states ``(antialias (6, 2), notch (3, 2), lowpass (3, 2))``; zeros if None.

    Returns
    -------
    torque : ndarray, shape (3,)
        Saturated torque ``u_n`` (N m).
    integral : ndarray, shape (3,)
        Integrator state ``z_{n+1}`` (rad s).
    filters : tuple of ndarray
        Filter states after the sample, shapes as given.
    """
    g, T, f = config.gains, config.sample_time, config.filters
    if filters is None:
        filters = (np.zeros((6, 2)), np.zeros((3, 2)), np.zeros((3, 2)))
    s_aa, s_notch, s_low = filters
    sampled = np.concatenate([np.asarray(attitude, dtype=float), np.asarray(rate, dtype=float)])
    sampled, s_aa = biquad_step(np.broadcast_to(f.antialias, (6, 5)), sampled, s_aa,
                                f.antialias_on)
    e = sampled[:3] - config.reference
    v = -(g.kp * e + g.kd * sampled[3:] + g.ki * integral)
    v, s_notch = biquad_step(f.notch, v, s_notch, f.notch_on)
    w, s_low = biquad_step(f.lowpass, v, s_low, f.lowpass_on)
    hmax = config.momentum_limit
    # keep momentum_next - u T within +-hmax, then enforce the torque limit
    u = np.clip(w, (momentum_next - hmax) / T, (momentum_next + hmax) / T)
    u = np.clip(u, -config.torque_limit, config.torque_limit)
    saturated = u != w
    dv = -g.ki * T * e  # change of the command the integration would cause
    winds_up = saturated & (np.sign(dv) == np.sign(w - u)) & config.anti_windup
    new_integral = np.where(winds_up, integral, integral + T * e)
    return u, new_integral, (s_aa, s_notch, s_low)


def acs_advance(config: AcsConfig, state: AcsState, h: float, attitude, rate) -> AcsState:
    """Advance the controller and wheels from ``state.time`` to ``state.time + h``.

    Every sample ``n T`` in ``[t, t + h)`` is taken with the held inputs; the torque
    computed at a sample becomes active one sample later; the wheel momentum is
    integrated exactly with the piecewise-constant active torque.

    Parameters
    ----------
    config : AcsConfig
        Controller parameters.
    state : AcsState
        State at ``t = state.time``.
    h : float
        Step (s), positive; need not be a multiple of the sample time.
    attitude : array_like, shape (3,)
        Roll, pitch, yaw held over the step (rad).
    rate : array_like, shape (3,)
        Body rates held over the step (rad/s).

    Returns
    -------
    AcsState
        State at ``t + h``.
    """
    if not h > 0:
        raise ValueError(f"ACS step size must be positive, got {h!r}")
    T = config.sample_time
    tol = 1e-6 * T
    t, t_end = state.time, state.time + h
    z = state.integral.copy()
    u_act = state.torque_active.copy()
    u_pend = state.torque_pending.copy()
    hw = state.momentum.copy()
    filters = (state.antialias.copy(), state.notch.copy(), state.lowpass.copy())
    n, activated = state.next_sample, state.activated
    if n * T < t - tol:  # a step started after a sample that was never taken
        n = math.ceil(t / T - 1e-6)
    cur = t
    while n * T < t_end - tol:
        tau = max(n * T, cur)
        hw -= u_act * (tau - cur)
        cur = tau
        if activated < n:
            u_act, activated = u_pend, n
        u_pend, z, filters = pid_command(config, z, attitude, rate, hw - u_act * T, filters)
        n += 1
    hw -= u_act * (t_end - cur)
    if abs(t_end - n * T) <= tol and activated < n:
        u_act, activated = u_pend, n
    return AcsState(z, u_act, u_pend, hw, n, activated, float(t_end), *filters)


def acs_outputs(config: AcsConfig, state: AcsState) -> tuple[np.ndarray, np.ndarray]:
    """Torque on the body and wheel speeds at the state's time.

    Parameters
    ----------
    config : AcsConfig
        Controller parameters.
    state : AcsState
        Current state.

    Returns
    -------
    torque : ndarray, shape (3,)
        Control torque on the body, ``Tx, Ty, Tz`` (N m).
    wheel_speed : ndarray, shape (3,)
        Wheel speeds relative to the body (rad/s).
    """
    return state.torque_active.copy(), state.momentum / config.wheel_inertia
