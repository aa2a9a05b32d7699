"""Stepping form of a disturbance source, as used by the disturbance FMU.

A time-driven source needs no state: the wrench at the end of a step is
``scale * source.wrench(t + h)`` inside ``[start, stop)``.  A wheel-imbalance source
driven by a wheel-speed *input* keeps the rotor angle ``theta`` and the held speed
``omega`` as state.  Over a step ``[t, t + h]`` the input is held (zero-order hold), so

    theta(t + h) = theta(t) + omega_in h,     wrench(t + h) = W(theta(t + h), omega_in),

where ``omega_in`` is the input value at the start of the step.  The output at the end of
a step therefore depends on the input only through the state: there is no direct
feedthrough from ``wheel_speed`` to the wrench, and setting the input does not change the
current output.  Before the first step the held speed is zero, so the initial wrench of
an input-driven wheel is zero.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from distfmu.sources import Source, SourceError, WheelImbalance, advance_wheel
from fmukit.timing import reached


@dataclass(frozen=True)
class DisturbanceConfig:
    """What a disturbance instance produces.

    Parameters
    ----------
    source : Source
        The disturbance source.
    scale : float
        Amplitude factor (dimensionless).
    start, stop : float
        The wrench is zero outside ``[start, stop)`` (s).
    speed_input : bool
        Drive a :class:`~distfmu.sources.WheelImbalance` source from the wheel-speed
        input instead of its own speed (ignored for other sources).
    """

    source: Source
    scale: float = 1.0
    start: float = 0.0
    stop: float = math.inf
    speed_input: bool = False

    def __post_init__(self):
        if not self.stop > self.start:
            raise SourceError(f"disturbance config: stop ({self.stop!r} s) must be after "
                              f"start ({self.start!r} s)")

    @property
    def input_driven(self) -> bool:
        """True when the wheel-speed input drives the source."""
        return self.speed_input and isinstance(self.source, WheelImbalance)


@dataclass(frozen=True)
class DisturbanceState:
    """State of an input-driven wheel (unused for time-driven sources).

    Parameters
    ----------
    time : float
        Time of the state (s).
    theta : float
        Rotor angle (rad).
    omega : float
        Wheel speed held over the last step (rad/s).
    """

    time: float = 0.0
    theta: float = 0.0
    omega: float = 0.0


def _gate(config: DisturbanceConfig, t: float, w: np.ndarray, period: float) -> np.ndarray:
    on = reached(t, config.start, period) and not reached(t, config.stop, period)
    return config.scale * w if on else np.zeros(6)


def disturbance_output(config: DisturbanceConfig, state: DisturbanceState,
                       period: float = 0.0) -> np.ndarray:
    """Wrench at the state's time.

    Parameters
    ----------
    config : DisturbanceConfig
        The disturbance.
    state : DisturbanceState
        Current state.
    period : float
        The step that ended at the state's time (s): the active window's edges are met
        within ``fmukit.timing.TIME_RTOL`` of it (a host's rounding of time); 0 for exact.

    Returns
    -------
    ndarray, shape (6,)
        ``[Fx, Fy, Fz, Mx, My, Mz]`` (N, N m).
    """
    t = state.time
    if config.input_driven:
        w = config.source.wrench_at(state.theta, state.omega)
    else:
        w = config.source.wrench(t)
    return _gate(config, t, np.asarray(w, dtype=float), period)


def disturbance_step(config: DisturbanceConfig, state: DisturbanceState, h: float,
                     wheel_speed: float = 0.0) -> DisturbanceState:
    """Advance a disturbance over one communication step.

    Parameters
    ----------
    config : DisturbanceConfig
        The disturbance.
    state : DisturbanceState
        State at the start of the step.
    h : float
        Step size (s), positive.
    wheel_speed : float
        Wheel-speed input held over the step (rad/s); used only when input driven.

    Returns
    -------
    DisturbanceState
        State at ``state.time + h``; read the wrench with :func:`disturbance_output`.
    """
    if not h > 0:
        raise ValueError(f"disturbance step size must be positive, got {h!r}")
    if config.input_driven:
        return replace(state, time=state.time + h,
                       theta=advance_wheel(state.theta, wheel_speed, h),
                       omega=float(wheel_speed))
    return replace(state, time=state.time + h)


def disturbance_series(config: DisturbanceConfig, times) -> np.ndarray:
    """Wrench at many communication points at once, for a time-driven source.

    The same values as :func:`disturbance_output` at each time (the FMU's output after
    the step that ends there), for the linear engine and other open-loop uses.

    Parameters
    ----------
    config : DisturbanceConfig
        The disturbance; an input-driven wheel has no series (its wrench follows the
        wheel-speed input) and raises :class:`~distfmu.sources.SourceError`.
    times : array_like, shape (n,)
        Communication points (s).

    Returns
    -------
    ndarray, shape (n, 6)
        ``[Fx, Fy, Fz, Mx, My, Mz]`` (N, N m) at each time.
    """
    if config.input_driven:
        raise SourceError("an input-driven wheel follows its wheel_speed input; it has no "
                          "open-loop series")
    t = np.asarray(times, dtype=float)
    w = np.asarray(config.source.wrench(t), dtype=float).reshape(t.shape + (6,))
    on = (config.start <= t) & (t < config.stop)
    return np.where(on[:, None], config.scale * w, 0.0)
