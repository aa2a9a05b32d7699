"""Discrete three-axis PID attitude control with reaction wheels (pure numerics, SI).

Control law, per body axis ``i``, sampled every ``T`` seconds at ``t_n = n T``::

    e_n  = theta_n - theta_ref
    v_n  = -(kp e_n + kd (omega_n - 0) + ki z_n)      (commanded torque, N m)
    u_n  = sat(v_n)                                   (torque and momentum limits)
    z_{n+1} = z_n + T e_n   unless the integration drives further into saturation

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
  torque is saturated and the new error would push the command further past the limit.

Time is handled by integer sample indices: :func:`acs_advance` processes every sample
``n T`` in ``[t, t + h)`` with the inputs held, so the result is the same whether a
master calls it once per sample or with larger or smaller steps (sub-stepping).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np


class AcsConfigError(ValueError):
    """ACS parameters are inconsistent (wrong shape, sign or value)."""


def _vec3(value, owner: str, name: str, positive: bool = False) -> np.ndarray:
    v = np.broadcast_to(np.asarray(value, dtype=float), (3,)).copy() \
        if np.ndim(value) == 0 else np.asarray(value, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise AcsConfigError(f"{owner}: {name} must be 3 finite numbers, got {value!r}")
    if positive and np.any(v <= 0):
        raise AcsConfigError(f"{owner}: {name} must be positive, got {value!r}")
    v.flags.writeable = False
    return v


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
    """

    gains: PidGains
    sample_time: float = 0.1
    torque_limit: np.ndarray = 0.4
    momentum_limit: np.ndarray = 75.0
    wheel_inertia: np.ndarray = 0.2
    reference: np.ndarray = 0.0
    anti_windup: bool = True

    def __post_init__(self):
        owner = "ACS config"
        if not (isinstance(self.sample_time, (int, float)) and math.isfinite(self.sample_time)
                and self.sample_time > 0):
            raise AcsConfigError(f"{owner}: sample_time must be a positive number, got "
                                 f"{self.sample_time!r}")
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
    """

    integral: np.ndarray = field(default_factory=lambda: np.zeros(3))
    torque_active: np.ndarray = field(default_factory=lambda: np.zeros(3))
    torque_pending: np.ndarray = field(default_factory=lambda: np.zeros(3))
    momentum: np.ndarray = field(default_factory=lambda: np.zeros(3))
    next_sample: int = 0
    activated: int = -1
    time: float = 0.0

    def as_array(self) -> np.ndarray:
        """Flatten to a float array of length 15 (for FMU state save/restore)."""
        return np.concatenate([self.integral, self.torque_active, self.torque_pending,
                               self.momentum, [self.next_sample, self.activated, self.time]])

    @classmethod
    def from_array(cls, a) -> AcsState:
        """Inverse of :meth:`as_array`."""
        a = np.asarray(a, dtype=float)
        if a.shape != (15,):
            raise AcsConfigError(f"ACS state array has shape {a.shape}; expected (15,)")
        return cls(a[0:3].copy(), a[3:6].copy(), a[6:9].copy(), a[9:12].copy(),
                   int(round(a[12])), int(round(a[13])), float(a[14]))


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


def pid_command(config: AcsConfig, integral, attitude, rate, momentum_next):
    """One sample of the control law: saturated torque and new integrator.

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

    Returns
    -------
    torque : ndarray, shape (3,)
        Saturated torque ``u_n`` (N m).
    integral : ndarray, shape (3,)
        Integrator state ``z_{n+1}`` (rad s).
    """
    g, T = config.gains, config.sample_time
    e = np.asarray(attitude, dtype=float) - config.reference
    v = -(g.kp * e + g.kd * np.asarray(rate, dtype=float) + g.ki * integral)
    hmax = config.momentum_limit
    # keep momentum_next - u T within +-hmax, then enforce the torque limit
    u = np.clip(v, (momentum_next - hmax) / T, (momentum_next + hmax) / T)
    u = np.clip(u, -config.torque_limit, config.torque_limit)
    saturated = u != v
    dv = -g.ki * T * e  # change of the command the integration would cause
    winds_up = saturated & (np.sign(dv) == np.sign(v - u)) & config.anti_windup
    new_integral = np.where(winds_up, integral, integral + T * e)
    return u, new_integral


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
        u_pend, z = pid_command(config, z, attitude, rate, hw - u_act * T)
        n += 1
    hw -= u_act * (t_end - cur)
    if abs(t_end - n * T) <= tol and activated < n:
        u_act, activated = u_pend, n
    return AcsState(z, u_act, u_pend, hw, n, activated, float(t_end))


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
