"""Disturbance sources as pure functions of time (SI units).

Every source is a frozen dataclass with one method,

    ``wrench(t) -> ndarray, shape t.shape + (6,)``

giving the force/torque vector ``[Fx, Fy, Fz, Mx, My, Mz]`` (N, N m) that the source
applies to the spacecraft at its mount, in spacecraft body axes.  ``t`` may be a scalar or
a numpy array (s); evaluation is vectorised and has no hidden state, so a source evaluated
twice at the same time gives the same value, and random sources are reproducible from
their ``seed``.  Where a mechanism moves an inertia (scan mirror, slewing telescope,
stepped solar array), the wrench is the *reaction* on the spacecraft: ``-J * alpha``.

The reaction-wheel source also has a stepping form (:func:`advance_wheel`) for a wheel
speed that arrives as an input signal: the rotor phase is then integrated from the held
speed instead of being a closed-form function of time.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Protocol

import numpy as np

WRENCH_NAMES = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
"""Names of the six wrench components, in order (N, N, N, N m, N m, N m)."""


class SourceError(ValueError):
    """A disturbance source was given inconsistent parameters or data."""


class Source(Protocol):
    """Anything with ``wrench(t) -> ndarray, shape t.shape + (6,)``."""

    def wrench(self, t) -> np.ndarray: ...


# --------------------------------------------------------------------------- helpers


def _unit(vector, owner: str, name: str = "direction") -> np.ndarray:
    v = np.asarray(vector, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise SourceError(f"{owner}: {name} must be 3 finite numbers, got {vector!r}")
    norm = float(np.linalg.norm(v))
    if norm == 0.0:
        raise SourceError(f"{owner}: {name} must be a non-zero vector, got {vector!r}")
    return v / norm


def _check_kind(kind: str, owner: str) -> None:
    if kind not in ("force", "torque"):
        raise SourceError(f"{owner}: kind must be 'force' or 'torque', got {kind!r}")


def _positive(value, owner: str, name: str) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise SourceError(f"{owner}: {name} must be a positive number, got {value!r}")


def _along(scalar: np.ndarray, direction: np.ndarray, kind: str) -> np.ndarray:
    """Place a scalar signal along a unit 3-vector in the force or torque half."""
    out = np.zeros(np.shape(scalar) + (6,))
    offset = 0 if kind == "force" else 3
    out[..., offset:offset + 3] = np.multiply.outer(scalar, direction)
    return out


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` over the last axis without BLAS, so results are bit-reproducible
    across processes and hosts (BLAS kernels may differ in the last bit)."""
    return np.einsum("...i,i->...", a, b)


def _perpendicular_pair(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ``e1, e2`` with ``(e1, e2, axis)`` right-handed."""
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    e1 = np.cross(helper, axis)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


# --------------------------------------------------------------------------- sources


@dataclass(frozen=True)
class Zero:
    """No disturbance: the wrench is zero at all times."""

    def wrench(self, t) -> np.ndarray:
        """Zero wrench, shape ``t.shape + (6,)`` (N, N m)."""
        return np.zeros(np.shape(t) + (6,))


@dataclass(frozen=True)
class Harmonic:
    """Fundamental plus harmonics along one axis (cryocoolers, imbalances).

    ``s(t) = sum_i a_i sin(2 pi h_i f0 t + phi_i)`` placed along ``direction``.

    Parameters
    ----------
    frequency : float
        Fundamental frequency ``f0`` (Hz).
    amplitudes : tuple of float, shape (n_harmonics,)
        Amplitude ``a_i`` of each harmonic (N for a force, N m for a torque).
    harmonics : tuple of float, shape (n_harmonics,), optional
        Harmonic numbers ``h_i`` (dimensionless); default ``1, 2, ..., n_harmonics``.
    phases : tuple of float, shape (n_harmonics,), optional
        Phase ``phi_i`` of each harmonic (rad); default zeros.
    direction : tuple of float, shape (3,)
        Axis of the force or torque in body axes (normalised here).
    kind : {"force", "torque"}
        Whether the signal is a force or a torque.
    """

    frequency: float
    amplitudes: tuple[float, ...]
    harmonics: tuple[float, ...] | None = None
    phases: tuple[float, ...] | None = None
    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)
    kind: str = "force"

    def __post_init__(self):
        name = "harmonic source"
        _positive(self.frequency, name, "frequency")
        _check_kind(self.kind, name)
        n = len(self.amplitudes)
        for label, seq in (("harmonics", self.harmonics), ("phases", self.phases)):
            if seq is not None and len(seq) != n:
                raise SourceError(
                    f"{name}: {label} has {len(seq)} entries; expected {n} (one per amplitude)"
                )
        _unit(self.direction, name)

    def wrench(self, t) -> np.ndarray:
        """Wrench at times ``t`` (s), shape ``t.shape + (6,)`` (N, N m)."""
        t = np.asarray(t, dtype=float)
        n = len(self.amplitudes)
        h = np.arange(1, n + 1) if self.harmonics is None else np.asarray(self.harmonics)
        phi = np.zeros(n) if self.phases is None else np.asarray(self.phases)
        arg = 2 * np.pi * self.frequency * np.multiply.outer(t, h) + phi
        s = _dot(np.sin(arg), np.asarray(self.amplitudes, dtype=float))
        return _along(s, _unit(self.direction, "harmonic source"), self.kind)


@dataclass(frozen=True)
class Chopper:
    """Square wave along one axis, with an optional linear rise time.

    The wave is ``+amplitude`` for the first ``duty`` fraction of each period and
    ``-amplitude`` for the rest; each edge is a linear ramp of duration ``rise_time``
    centred on the ideal switching instant (``rise_time = 0`` gives a sharp square wave,
    whose Fourier series is ``4 a / (pi k)`` at odd harmonics ``k`` for ``duty = 0.5``).

    Parameters
    ----------
    frequency : float
        Chopping frequency (Hz).
    amplitude : float
        Half peak-to-peak value (N or N m).
    direction : tuple of float, shape (3,)
        Axis in body axes.
    kind : {"force", "torque"}
        Whether the signal is a force or a torque.
    rise_time : float
        Duration of each edge (s), ``0 <= rise_time < min(duty, 1 - duty) / frequency``.
    duty : float
        Fraction of the period at ``+amplitude`` (dimensionless, in (0, 1)).
    phase : float
        Time offset of the first rising edge as a fraction of the period (dimensionless).
    """

    frequency: float
    amplitude: float
    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)
    kind: str = "torque"
    rise_time: float = 0.0
    duty: float = 0.5
    phase: float = 0.0

    def __post_init__(self):
        name = "chopper source"
        _positive(self.frequency, name, "frequency")
        _check_kind(self.kind, name)
        _unit(self.direction, name)
        if not 0.0 < self.duty < 1.0:
            raise SourceError(f"{name}: duty must be in (0, 1), got {self.duty!r}")
        limit = min(self.duty, 1 - self.duty) / self.frequency
        if not 0.0 <= self.rise_time < limit:
            raise SourceError(
                f"{name}: rise_time must be in [0, {limit:g}) s, got {self.rise_time!r}"
            )

    def wrench(self, t) -> np.ndarray:
        """Wrench at times ``t`` (s), shape ``t.shape + (6,)`` (N, N m)."""
        t = np.asarray(t, dtype=float)
        period = 1.0 / self.frequency
        # time since the rising edge, in [-period/2, period/2) around it
        x = np.mod(t / period - self.phase, 1.0) * period
        high = self.duty * period
        s = np.where(x < high, 1.0, -1.0)
        if self.rise_time > 0:
            half = 0.5 * self.rise_time
            # rising edge at x = 0 (and x = period), falling edge at x = high
            d_rise = np.minimum(x, period - x) * np.where(x < period / 2, 1.0, -1.0)
            d_fall = x - high
            s = np.where(np.abs(d_rise) < half, d_rise / half, s)
            s = np.where(np.abs(d_fall) < half, -d_fall / half, s)
        return _along(self.amplitude * s, _unit(self.direction, "chopper source"), self.kind)


@dataclass(frozen=True)
class ScanMirror:
    """Reaction torque of a constant-rate scan mirror with retrace.

    The mirror sweeps ``-amplitude -> +amplitude`` at constant rate in
    ``(1 - retrace_fraction) * period`` and returns in ``retrace_fraction * period``.
    Each change of rate is a linear velocity ramp of duration ``turnaround`` centred on
    the ideal reversal, so outside the turnarounds the angle is exactly the ideal
    triangle wave; inside, the corners are rounded by ``dw * turnaround / 8``.  The torque on the
    spacecraft is ``-inertia * alpha`` about ``axis``: a pulse of
    ``inertia * (w_scan - w_retrace) / turnaround`` at each reversal.

    Parameters
    ----------
    inertia : float
        Mirror inertia about its rotation axis (kg m^2).
    period : float
        Scan period, sweep plus retrace (s).
    amplitude : float
        Half of the sweep angle (rad).
    retrace_fraction : float
        Fraction of the period spent on the retrace (dimensionless, in (0, 1)).
    turnaround : float
        Duration of each reversal (s); must be shorter than both sweep and retrace.
    axis : tuple of float, shape (3,)
        Mirror rotation axis in body axes.
    """

    inertia: float
    period: float
    amplitude: float
    retrace_fraction: float = 0.1
    turnaround: float = 0.05
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)

    def __post_init__(self):
        name = "scan mirror source"
        for f in ("inertia", "period", "amplitude", "turnaround"):
            _positive(getattr(self, f), name, f)
        _unit(self.axis, name, "axis")
        r = self.retrace_fraction
        if not 0.0 < r < 1.0:
            raise SourceError(f"{name}: retrace_fraction must be in (0, 1), got {r!r}")
        shortest = min(r, 1 - r) * self.period
        if self.turnaround >= shortest:
            raise SourceError(
                f"{name}: turnaround must be shorter than the retrace and the sweep "
                f"({shortest:g} s), got {self.turnaround!r} s"
            )

    @property
    def scan_rate(self) -> float:
        """Mirror rate during the sweep (rad/s)."""
        return 2 * self.amplitude / ((1 - self.retrace_fraction) * self.period)

    @property
    def retrace_rate(self) -> float:
        """Mirror rate during the retrace (rad/s), negative."""
        return -2 * self.amplitude / (self.retrace_fraction * self.period)

    def acceleration(self, t) -> np.ndarray:
        """Mirror angular acceleration at ``t`` (rad/s^2), shape ``t.shape``."""
        t = np.asarray(t, dtype=float)
        x = np.mod(t, self.period)
        t_sweep = (1 - self.retrace_fraction) * self.period
        half = 0.5 * self.turnaround
        jump = (self.scan_rate - self.retrace_rate) / self.turnaround
        at_start = (x < half) | (x >= self.period - half)  # retrace -> sweep
        at_end = np.abs(x - t_sweep) < half  # sweep -> retrace
        return np.where(at_start, jump, 0.0) - np.where(at_end, jump, 0.0)

    def wrench(self, t) -> np.ndarray:
        """Reaction wrench at times ``t`` (s), shape ``t.shape + (6,)`` (N, N m)."""
        torque = -self.inertia * self.acceleration(t)
        return _along(torque, _unit(self.axis, "scan mirror source", "axis"), "torque")


@dataclass(frozen=True)
class Slew:
    """Bang-coast-bang pointing slew of an instrument: reaction torque.

    The instrument accelerates at ``max_accel`` until it reaches ``max_rate`` (or, for a
    short slew, until half the angle: a triangular profile), coasts, and decelerates
    symmetrically, covering exactly ``angle``.  The torque on the spacecraft is
    ``-inertia * alpha`` about ``axis``.  With ``repeat`` the manoeuvre recurs every
    ``repeat`` seconds after ``start``; with ``alternate`` every second slew goes back,
    so the instrument oscillates between two pointings instead of drifting.

    Parameters
    ----------
    angle : float
        Slew angle (rad), may be negative.
    max_rate : float
        Rate limit (rad/s).
    max_accel : float
        Acceleration limit (rad/s^2).
    inertia : float
        Inertia of the slewed instrument about ``axis`` (kg m^2).
    start : float
        Start time of the first slew (s).
    axis : tuple of float, shape (3,)
        Slew axis in body axes.
    repeat : float or None
        Period between slew starts (s), at least the slew duration; ``None`` slews once.
    alternate : bool
        Reverse the direction of every second slew when repeating.
    """

    angle: float
    max_rate: float
    max_accel: float
    inertia: float
    start: float = 0.0
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    repeat: float | None = None
    alternate: bool = True

    def __post_init__(self):
        name = "slew source"
        for f in ("max_rate", "max_accel", "inertia"):
            _positive(getattr(self, f), name, f)
        if not math.isfinite(self.angle) or self.angle == 0:
            raise SourceError(f"{name}: angle must be a non-zero finite number, got {self.angle!r}")
        _unit(self.axis, name, "axis")
        if self.repeat is not None and not self.repeat >= self.duration:
            raise SourceError(
                f"{name}: repeat must be at least the slew duration {self.duration:g} s, "
                f"got {self.repeat!r}"
            )

    @property
    def accel_time(self) -> float:
        """Duration of the acceleration (and of the deceleration) phase (s)."""
        return min(self.max_rate / self.max_accel, math.sqrt(abs(self.angle) / self.max_accel))

    @property
    def coast_time(self) -> float:
        """Duration of the constant-rate phase (s)."""
        ta = self.accel_time
        peak = self.max_accel * ta
        return max(abs(self.angle) - peak * ta, 0.0) / peak

    @property
    def duration(self) -> float:
        """Duration of one slew (s)."""
        return 2 * self.accel_time + self.coast_time

    def _local(self, t):
        """Time since the current slew started (s) and the slew's sign."""
        t = np.asarray(t, dtype=float)
        tau = t - self.start
        sign = np.full(t.shape, math.copysign(1.0, self.angle))
        if self.repeat is not None:
            k = np.floor(np.maximum(tau, 0.0) / self.repeat)
            tau = np.where(tau >= 0, tau - k * self.repeat, tau)
            if self.alternate:
                sign = sign * np.where(np.mod(k, 2) == 1, -1.0, 1.0)
        return tau, sign

    def acceleration(self, t) -> np.ndarray:
        """Instrument angular acceleration at ``t`` (rad/s^2), shape ``t.shape``."""
        tau, sign = self._local(t)
        ta, tc = self.accel_time, self.coast_time
        acc = np.where((tau >= 0) & (tau < ta), 1.0, 0.0)
        acc -= np.where((tau >= ta + tc) & (tau < 2 * ta + tc), 1.0, 0.0)
        return sign * self.max_accel * acc

    def rate(self, t) -> np.ndarray:
        """Instrument angular rate at ``t`` (rad/s), shape ``t.shape``."""
        tau, sign = self._local(t)
        ta, tc = self.accel_time, self.coast_time
        a = self.max_accel
        up = a * np.clip(tau, 0.0, ta)
        down = a * np.clip(tau - ta - tc, 0.0, ta)
        return sign * (up - down)

    def wrench(self, t) -> np.ndarray:
        """Reaction wrench at times ``t`` (s), shape ``t.shape + (6,)`` (N, N m)."""
        torque = -self.inertia * self.acceleration(t)
        return _along(torque, _unit(self.axis, "slew source", "axis"), "torque")


@dataclass(frozen=True)
class Stepper:
    """Solar-array-drive steps: a torque pulse (pair) at each step.

    Each step is a half-sine torque pulse of peak ``peak_torque`` and width
    ``pulse_width``; with ``bipolar`` it is followed by an opposite pulse (the rotor
    accelerates then stops on the next detent), so the mean torque is zero.

    Parameters
    ----------
    step_rate : float
        Steps per second (Hz).
    peak_torque : float
        Peak of each pulse (N m).
    pulse_width : float
        Width of each half-sine pulse (s); ``pulse_width * (2 if bipolar else 1)`` must
        not exceed the step period.
    axis : tuple of float, shape (3,)
        Drive axis in body axes.
    bipolar : bool
        Add the opposite (stopping) pulse after each driving pulse.
    """

    step_rate: float
    peak_torque: float
    pulse_width: float
    axis: tuple[float, float, float] = (0.0, 1.0, 0.0)
    bipolar: bool = True

    def __post_init__(self):
        name = "stepper source"
        for f in ("step_rate", "peak_torque", "pulse_width"):
            _positive(getattr(self, f), name, f)
        _unit(self.axis, name, "axis")
        used = self.pulse_width * (2 if self.bipolar else 1)
        if used > 1.0 / self.step_rate:
            raise SourceError(
                f"{name}: pulses take {used:g} s, longer than the step period "
                f"{1.0 / self.step_rate:g} s"
            )

    @property
    def impulse(self) -> float:
        """Angular impulse of one driving pulse (N m s): ``2 T w / pi``."""
        return 2.0 * self.peak_torque * self.pulse_width / math.pi

    def wrench(self, t) -> np.ndarray:
        """Wrench at times ``t`` (s), shape ``t.shape + (6,)`` (N, N m)."""
        t = np.asarray(t, dtype=float)
        x = np.mod(t, 1.0 / self.step_rate)
        w = self.pulse_width
        s = np.where(x < w, np.sin(np.pi * x / w), 0.0)
        if self.bipolar:
            s -= np.where((x >= w) & (x < 2 * w), np.sin(np.pi * (x - w) / w), 0.0)
        return _along(self.peak_torque * s, _unit(self.axis, "stepper source", "axis"),
                      "torque")


# --------------------------------------------------------------------------- wheel


@dataclass(frozen=True)
class SpeedProfile:
    """Piecewise-linear wheel speed ``Omega(t)`` held constant outside the samples.

    Parameters
    ----------
    times : tuple of float, shape (n,)
        Strictly increasing sample times (s).
    speeds : tuple of float, shape (n,)
        Wheel speed at each sample (rad/s).
    """

    times: tuple[float, ...]
    speeds: tuple[float, ...]

    def __post_init__(self):
        t = np.asarray(self.times, dtype=float)
        if t.ndim != 1 or t.size < 1 or len(self.speeds) != t.size:
            raise SourceError(
                f"speed profile: times and speeds must be 1-D of equal length >= 1, got "
                f"{len(self.times)} and {len(self.speeds)}"
            )
        if np.any(np.diff(t) <= 0):
            raise SourceError("speed profile: times must be strictly increasing")

    def speed(self, t) -> np.ndarray:
        """Wheel speed at ``t`` (rad/s)."""
        return np.interp(t, self.times, self.speeds)

    def _integral(self, t) -> np.ndarray:
        """Integral of the speed from the first sample time to ``t`` (rad)."""
        t = np.asarray(t, dtype=float)
        knots = np.asarray(self.times, dtype=float)
        w = np.asarray(self.speeds, dtype=float)
        before = w[0] * (np.minimum(t, knots[0]) - knots[0])
        if knots.size == 1:
            return before + w[0] * (np.maximum(t, knots[0]) - knots[0])
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(knots))])
        tc = np.clip(t, knots[0], knots[-1])
        i = np.clip(np.searchsorted(knots, tc, side="right") - 1, 0, knots.size - 2)
        dt = tc - knots[i]
        slope = (w[i + 1] - w[i]) / (knots[i + 1] - knots[i])
        inside = cum[i] + w[i] * dt + 0.5 * slope * dt**2
        after = w[-1] * (np.maximum(t, knots[-1]) - knots[-1])
        return before + inside + after

    def phase(self, t) -> np.ndarray:
        """Rotor angle ``integral_0^t Omega dt`` (rad), exact for the linear profile."""
        return self._integral(t) - self._integral(0.0)


@dataclass(frozen=True)
class WheelImbalance:
    """Reaction-wheel imbalance in Masterson's form.

    For wheel speed ``Omega`` and rotor angle ``theta`` (``d theta / dt = Omega``):

    * radial force, two components in the wheel plane (a vector rotating with the rotor),
      ``F1 = sum_i C_i Omega^2 sin(h_i theta + phi_i)``,
      ``F2 = sum_i C_i Omega^2 cos(h_i theta + phi_i)``;
    * rocking torque about the same two in-plane axes with coefficients ``D_i``;
    * axial force ``Fa = sum_i A_i Omega^2 sin(h_i theta + phi_i)`` (optional).

    The fundamental (``h = 1``) coefficients are the static imbalance ``Us`` (kg m) for
    the force and the dynamic imbalance ``Ud`` (kg m^2) for the torque.

    Parameters
    ----------
    harmonics : tuple of float, shape (n,)
        Harmonic numbers ``h_i`` (dimensionless), ``h_0 = 1`` for the fundamental.
    force_coeffs : tuple of float, shape (n,)
        Radial force coefficients ``C_i`` (kg m).
    torque_coeffs : tuple of float, shape (n,)
        Rocking torque coefficients ``D_i`` (kg m^2).
    axial_coeffs : tuple of float, shape (n,), optional
        Axial force coefficients ``A_i`` (kg m); default zeros.
    phases : tuple of float, shape (n,), optional
        Phase ``phi_i`` of each harmonic (rad); default zeros.
    speed : float or SpeedProfile
        Constant wheel speed (rad/s) or a speed profile.
    axis : tuple of float, shape (3,)
        Spin axis in body axes.
    """

    harmonics: tuple[float, ...]
    force_coeffs: tuple[float, ...]
    torque_coeffs: tuple[float, ...]
    axial_coeffs: tuple[float, ...] | None = None
    phases: tuple[float, ...] | None = None
    speed: float | SpeedProfile = 0.0
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)

    def __post_init__(self):
        name = "wheel imbalance source"
        n = len(self.harmonics)
        for label in ("force_coeffs", "torque_coeffs", "axial_coeffs", "phases"):
            seq = getattr(self, label)
            if seq is not None and len(seq) != n:
                raise SourceError(
                    f"{name}: {label} has {len(seq)} entries; expected {n} (one per harmonic)"
                )
        _unit(self.axis, name, "axis")
        if not isinstance(self.speed, SpeedProfile) and not math.isfinite(self.speed):
            raise SourceError(f"{name}: speed must be finite, got {self.speed!r}")

    @cached_property
    def _frame(self) -> np.ndarray:
        a = _unit(self.axis, "wheel imbalance source", "axis")
        e1, e2 = _perpendicular_pair(a)
        return np.stack([e1, e2, a])

    def phase(self, t) -> np.ndarray:
        """Rotor angle at ``t`` (rad), zero at ``t = 0``."""
        if isinstance(self.speed, SpeedProfile):
            return self.speed.phase(t)
        return self.speed * np.asarray(t, dtype=float)

    def speed_at(self, t) -> np.ndarray:
        """Wheel speed at ``t`` (rad/s)."""
        if isinstance(self.speed, SpeedProfile):
            return self.speed.speed(t)
        return np.full(np.shape(t), float(self.speed))

    def wrench_at(self, theta, omega) -> np.ndarray:
        """Wrench for rotor angle ``theta`` (rad) and speed ``omega`` (rad/s).

        Parameters
        ----------
        theta, omega : array_like, same shape
            Rotor angle (rad) and wheel speed (rad/s).

        Returns
        -------
        ndarray, shape ``theta.shape + (6,)``
            ``[Fx, Fy, Fz, Mx, My, Mz]`` (N, N m).
        """
        theta = np.asarray(theta, dtype=float)
        n = len(self.harmonics)
        h = np.asarray(self.harmonics, dtype=float)
        phi = np.zeros(n) if self.phases is None else np.asarray(self.phases, dtype=float)
        arg = np.multiply.outer(theta, h) + phi
        s, c = np.sin(arg), np.cos(arg)
        w2 = np.asarray(omega, dtype=float) ** 2
        C = np.asarray(self.force_coeffs, dtype=float)
        D = np.asarray(self.torque_coeffs, dtype=float)
        A = np.zeros(n) if self.axial_coeffs is None else np.asarray(self.axial_coeffs, float)
        local_f = np.stack([_dot(s, C), _dot(c, C), _dot(s, A)], axis=-1) * w2[..., None]
        local_m = np.stack([_dot(s, D), _dot(c, D), np.zeros(theta.shape)],
                           axis=-1) * w2[..., None]
        frame = self._frame  # rows e1, e2, axis
        return np.concatenate([np.einsum("...i,ij->...j", local_f, frame),
                               np.einsum("...i,ij->...j", local_m, frame)], axis=-1)

    def wrench(self, t) -> np.ndarray:
        """Wrench at times ``t`` (s) for the constant or profiled speed (N, N m)."""
        return self.wrench_at(self.phase(t), self.speed_at(t))

    def lines(self, speed: float) -> tuple[np.ndarray, np.ndarray]:
        """The spectral lines of the wrench at a constant wheel speed.

        ``wrench(t) = sum_i Re(a_i exp(j 2 pi f_i t))`` with ``theta = speed t``.

        Parameters
        ----------
        speed : float
            Wheel speed (rad/s).

        Returns
        -------
        freqs : ndarray, shape (n_harmonics,)
            ``f_i = h_i |speed| / (2 pi)`` (Hz).
        phasors : ndarray, shape (n_harmonics, 6), complex
            ``a_i`` for ``[Fx, Fy, Fz, Mx, My, Mz]`` (N, N m).
        """
        n = len(self.harmonics)
        h = np.asarray(self.harmonics, dtype=float)
        phi = np.zeros(n) if self.phases is None else np.asarray(self.phases, dtype=float)
        C = np.asarray(self.force_coeffs, dtype=float)
        D = np.asarray(self.torque_coeffs, dtype=float)
        A = np.zeros(n) if self.axial_coeffs is None else np.asarray(self.axial_coeffs, float)
        # sin(h theta + phi) = Re(-j e^{j(h theta + phi)}), cos(...) = Re(e^{j(...)});
        # a negative speed runs theta backwards: the conjugate line at |h speed|
        e = np.exp(1j * phi) * speed**2
        local_f = np.stack([-1j * C, C + 0j, -1j * A], axis=-1) * e[:, None]
        local_m = np.stack([-1j * D, D + 0j, np.zeros(n, complex)], axis=-1) * e[:, None]
        frame = self._frame
        ph = np.concatenate([local_f @ frame, local_m @ frame], axis=-1)
        if speed < 0:
            ph = ph.conj()
        return h * abs(speed) / (2 * np.pi), ph


def advance_wheel(theta: float, omega: float, dt: float) -> float:
    """Advance the rotor angle over a step with the wheel speed held.

    This is the stepping form for an input-driven wheel speed: between communication
    points the speed input is held (zero-order hold), so the angle integral is exact,
    ``theta + omega * dt``.  The result is wrapped into ``[0, 2 pi)`` only for whole
    turns of every integer harmonic; it is not wrapped at all (non-integer harmonics such
    as ``h = 2.9`` need the unwrapped angle), so a float64 angle keeps about 1e-9 rad
    resolution up to 1e7 rad.

    Parameters
    ----------
    theta : float
        Rotor angle at the start of the step (rad).
    omega : float
        Held wheel speed (rad/s).
    dt : float
        Step duration (s).

    Returns
    -------
    float
        Rotor angle at the end of the step (rad).
    """
    return float(theta + omega * dt)


# --------------------------------------------------------------------------- table


@dataclass(frozen=True, eq=False)
class Table:
    """Replay of a measured wrench history with linear interpolation.

    Outside the sampled interval the wrench is zero (``fill="zero"``) or the first/last
    sample (``fill="hold"``).

    Parameters
    ----------
    times : ndarray, shape (n,)
        Strictly increasing sample times (s).
    values : ndarray, shape (n, 6)
        ``[Fx, Fy, Fz, Mx, My, Mz]`` at each sample (N, N m).
    fill : {"zero", "hold"}
        Value outside ``[times[0], times[-1]]``.
    """

    times: np.ndarray
    values: np.ndarray
    fill: str = "zero"

    def __post_init__(self):
        t = np.asarray(self.times, dtype=float)
        v = np.asarray(self.values, dtype=float)
        if t.ndim != 1 or t.size < 2:
            raise SourceError(f"table source: times must be 1-D with at least 2 samples, "
                              f"got shape {t.shape}")
        if v.shape != (t.size, 6):
            raise SourceError(f"table source: values have shape {v.shape}; expected "
                              f"({t.size}, 6)")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
            raise SourceError("table source: times and values must be finite")
        bad = np.flatnonzero(np.diff(t) <= 0)
        if bad.size:
            i = int(bad[0])
            raise SourceError(
                f"table source: time must be strictly increasing, but sample {i + 1} "
                f"(t = {float(t[i + 1])!r} s) follows t = {float(t[i])!r} s"
            )
        if self.fill not in ("zero", "hold"):
            raise SourceError(f"table source: fill must be 'zero' or 'hold', got {self.fill!r}")
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "values", v)

    @classmethod
    def from_csv(cls, path, columns=None, time_column: str = "time",
                 fill: str = "zero") -> Table:
        """Read a wrench history from a CSV file.

        The file has a header row.  By default the columns named ``time`` and
        ``Fx, Fy, Fz, Mx, My, Mz`` are used; ``columns`` maps other names, as a sequence
        of six header names in wrench order.  Unknown extra columns are ignored.

        Parameters
        ----------
        path : str or Path
            CSV file.
        columns : sequence of str, shape (6,), optional
            Header names for ``Fx .. Mz`` in order; default :data:`WRENCH_NAMES`.
        time_column : str
            Header name of the time column (s).
        fill : {"zero", "hold"}
            Value outside the sampled interval.

        Returns
        -------
        Table
        """
        path = Path(path)
        wanted = list(WRENCH_NAMES if columns is None else columns)
        if len(wanted) != 6:
            raise SourceError(f"table CSV {path}: columns must name 6 wrench components, "
                              f"got {len(wanted)}")
        with path.open(newline="") as fh:
            rows = [r for r in csv.reader(fh) if r and any(c.strip() for c in r)]
        if not rows:
            raise SourceError(f"table CSV {path}: file is empty")
        header = [c.strip() for c in rows[0]]
        missing = [c for c in [time_column, *wanted] if c not in header]
        if missing:
            raise SourceError(
                f"table CSV {path}: missing column(s) {missing}; header has {header}"
            )
        idx = [header.index(c) for c in [time_column, *wanted]]
        try:
            data = np.array([[float(r[i]) for i in idx] for r in rows[1:]], dtype=float)
        except (ValueError, IndexError) as exc:
            raise SourceError(f"table CSV {path}: non-numeric or short row ({exc})") from exc
        if data.shape[0] < 2:
            raise SourceError(f"table CSV {path}: needs at least 2 data rows, got "
                              f"{data.shape[0]}")
        return cls(data[:, 0], data[:, 1:], fill=fill)

    def wrench(self, t) -> np.ndarray:
        """Linearly interpolated wrench at ``t`` (s), shape ``t.shape + (6,)``."""
        t = np.asarray(t, dtype=float)
        flat = t.reshape(-1)
        out = np.empty((flat.size, 6))
        for j in range(6):
            if self.fill == "hold":
                out[:, j] = np.interp(flat, self.times, self.values[:, j])
            else:
                out[:, j] = np.interp(flat, self.times, self.values[:, j], left=0.0, right=0.0)
        return out.reshape(t.shape + (6,))


# --------------------------------------------------------------------------- random


@dataclass(frozen=True)
class BandLimitedRandom:
    """Stationary random signal with a prescribed one-sided PSD, reproducible.

    Synthesis (inverse FFT on a fixed grid): a record of ``n_samples`` points at
    ``sample_rate`` is built once from the seed as a sum of cosines at the grid
    frequencies ``f_k = k / T`` (``T = n_samples / sample_rate``) with amplitudes
    ``a_k = sqrt(2 S(f_k) df)`` and phases uniform in ``[0, 2 pi)`` drawn with
    ``numpy.random.default_rng(seed)``; the one-sided PSD of the record is then ``S`` at
    every grid frequency and its variance is ``sum S df``.  ``S`` is the linear
    interpolation of ``(psd_freqs, psd_values)``, zero outside.  The record repeats with
    period ``T``; between grid points it is linearly interpolated, which attenuates the
    PSD by ``sinc^4(f / sample_rate)`` (under 2 % for ``f < sample_rate / 20``; choose
    ``sample_rate`` accordingly).  The signal is a pure function of ``(seed, t)``.

    Parameters
    ----------
    psd_freqs : tuple of float, shape (m,)
        Increasing frequencies of the PSD breakpoints (Hz).
    psd_values : tuple of float, shape (m,)
        One-sided PSD at the breakpoints (N^2/Hz or (N m)^2/Hz).
    seed : int
        Seed of the phases.
    sample_rate : float
        Grid rate (Hz); above twice the highest PSD frequency.
    n_samples : int
        Grid length (even); the record period is ``n_samples / sample_rate``.
    direction : tuple of float, shape (3,)
        Axis in body axes.
    kind : {"force", "torque"}
        Whether the signal is a force or a torque.
    """

    psd_freqs: tuple[float, ...]
    psd_values: tuple[float, ...]
    seed: int = 0
    sample_rate: float = 1000.0
    n_samples: int = 2**20
    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)
    kind: str = "force"

    def __post_init__(self):
        name = "band-limited random source"
        f = np.asarray(self.psd_freqs, dtype=float)
        s = np.asarray(self.psd_values, dtype=float)
        if f.ndim != 1 or f.shape != s.shape or f.size < 2:
            raise SourceError(f"{name}: psd_freqs and psd_values must be 1-D of equal length "
                              f">= 2, got {f.shape} and {s.shape}")
        if np.any(np.diff(f) <= 0) or f[0] < 0:
            raise SourceError(f"{name}: psd_freqs must be non-negative and increasing")
        if np.any(s < 0) or not np.all(np.isfinite(s)):
            raise SourceError(f"{name}: psd_values must be finite and non-negative")
        _positive(self.sample_rate, name, "sample_rate")
        if f[-1] >= self.sample_rate / 2:
            raise SourceError(f"{name}: highest PSD frequency {f[-1]:g} Hz must be below "
                              f"half the sample_rate ({self.sample_rate / 2:g} Hz)")
        if not (isinstance(self.n_samples, int) and self.n_samples >= 16
                and self.n_samples % 2 == 0):
            raise SourceError(f"{name}: n_samples must be an even integer >= 16, got "
                              f"{self.n_samples!r}")
        _check_kind(self.kind, name)
        _unit(self.direction, name)

    @property
    def period(self) -> float:
        """Record length after which the signal repeats (s)."""
        return self.n_samples / self.sample_rate

    def psd(self, f) -> np.ndarray:
        """Requested one-sided PSD at ``f`` (Hz), in (unit)^2/Hz."""
        return np.interp(f, self.psd_freqs, self.psd_values, left=0.0, right=0.0)

    @cached_property
    def record(self) -> np.ndarray:
        """The synthesised grid record, shape (n_samples,) (N or N m)."""
        n = self.n_samples
        df = self.sample_rate / n
        k = np.arange(n // 2 + 1)
        amp = np.sqrt(2.0 * self.psd(k * df) * df)
        amp[0] = 0.0
        amp[-1] = 0.0
        rng = np.random.default_rng(self.seed)
        phase = rng.uniform(0.0, 2 * np.pi, size=k.size)
        spectrum = 0.5 * n * amp * np.exp(1j * phase)
        return np.fft.irfft(spectrum, n)

    def signal(self, t) -> np.ndarray:
        """Scalar random signal at ``t`` (s), shape ``t.shape``."""
        t = np.asarray(t, dtype=float)
        x = np.mod(t * self.sample_rate, self.n_samples)
        i = np.floor(x).astype(np.int64)
        frac = x - i
        i %= self.n_samples
        rec = self.record
        return (1 - frac) * rec[i] + frac * rec[(i + 1) % self.n_samples]

    def wrench(self, t) -> np.ndarray:
        """Wrench at times ``t`` (s), shape ``t.shape + (6,)`` (N, N m)."""
        return _along(self.signal(t), _unit(self.direction, "band-limited random source"),
                      self.kind)


# --------------------------------------------------------------------------- combinators


@dataclass(frozen=True)
class Sum:
    """Sum of several sources acting at the same mount.

    Parameters
    ----------
    sources : tuple of Source
        The sources to add.
    """

    sources: tuple = field(default_factory=tuple)

    def wrench(self, t) -> np.ndarray:
        """Sum of the sources' wrenches at ``t`` (s) (N, N m)."""
        out = np.zeros(np.shape(t) + (6,))
        for s in self.sources:
            out = out + s.wrench(t)
        return out


@dataclass(frozen=True)
class Gated:
    """A source scaled and switched on only for ``start <= t < stop``.

    The inner source keeps its own (absolute) time base: gating does not shift it.

    Parameters
    ----------
    source : Source
        The source to gate.
    scale : float
        Amplitude factor (dimensionless).
    start, stop : float
        Active interval (s); ``stop = inf`` for no end.
    """

    source: object
    scale: float = 1.0
    start: float = 0.0
    stop: float = math.inf

    def __post_init__(self):
        if not self.stop > self.start:
            raise SourceError(f"gated source: stop ({self.stop!r} s) must be after start "
                              f"({self.start!r} s)")

    def wrench(self, t) -> np.ndarray:
        """Gated, scaled wrench at ``t`` (s) (N, N m)."""
        t = np.asarray(t, dtype=float)
        on = (t >= self.start) & (t < self.stop)
        return self.scale * on[..., None] * self.source.wrench(t)
