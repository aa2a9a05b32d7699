"""PID design for a rigid body ``J s^2`` and the loop it closes (python-control).

Design by loop shaping at the crossover ``w_c = 2 pi bandwidth``.  With the PID in the
ideal form ``C(s) = kp (1 + 1/(Ti s) + Td s)`` and the plant ``1 / (J s^2)`` (phase
-180 deg), the phase margin is the phase of ``C`` at ``w_c``.  Choosing
``Ti = b / w_c`` (integral zero a factor ``b`` below crossover) and
``Td = (tan(phi) + 1/b) / w_c`` gives ``arg C(j w_c) = phi``; ``|L(j w_c)| = 1`` then
fixes ``kp = J w_c^2 cos(phi)``.  The sampled loop loses about ``1.5 w_c T`` rad of phase
(half a sample for the zero-order hold, one sample for the computational delay of
:mod:`acsfmu.pid`), so ``phi`` is the requested margin plus that lag.

:func:`discrete_loop` builds the exact sampled loop (plant discretised with a
zero-order hold, controller with its delay) so that margins and bandwidths are those of
the implementation in :mod:`acsfmu.pid`, not of a continuous idealisation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from acsfmu.pid import AcsConfigError, PidGains


@dataclass(frozen=True)
class AxisDesign:
    """Gains of one axis and the sampled loop's figures of merit.

    Parameters
    ----------
    kp, ki, kd : float
        Parallel PID gains (N m/rad, N m/(rad s), N m s/rad).
    crossover : float
        Gain crossover frequency of the sampled loop (Hz).
    phase_margin : float
        Phase margin of the sampled loop (deg).
    gain_margin : float
        Upper gain margin of the sampled loop (dimensionless, inf if none).  The loop is
        also conditionally stable at low frequency (integrator on a double integrator):
        lowering the gain by a factor of about 4 destabilises it.
    bandwidth : float
        -3 dB frequency of the closed loop ``L / (1 + L)`` (Hz).
    """

    kp: float
    ki: float
    kd: float
    crossover: float
    phase_margin: float
    gain_margin: float
    bandwidth: float

    def __iter__(self):
        return iter((self.kp, self.ki, self.kd))


def pid_gains_for(inertia: float, bandwidth: float = 0.1, phase_margin: float = 50.0,
                  sample_time: float = 0.1, integral_ratio: float = 5.0
                  ) -> tuple[float, float, float]:
    """PID gains placing the crossover of ``C / (J s^2)`` at ``bandwidth``.

    Parameters
    ----------
    inertia : float
        Body inertia about the axis (kg m^2).
    bandwidth : float
        Desired gain crossover frequency (Hz).
    phase_margin : float
        Desired phase margin of the sampled loop (deg).
    sample_time : float
        Controller sample time (s); 0 for no delay compensation.
    integral_ratio : float
        ``b = Ti w_c``: how far below crossover the integral zero sits (dimensionless).

    Returns
    -------
    kp, ki, kd : float
        Parallel gains (N m/rad, N m/(rad s), N m s/rad).
    """
    for name, value in (("inertia", inertia), ("bandwidth", bandwidth),
                        ("integral_ratio", integral_ratio)):
        if not (math.isfinite(value) and value > 0):
            raise AcsConfigError(f"PID design: {name} must be positive, got {value!r}")
    if sample_time < 0:
        raise AcsConfigError(f"PID design: sample_time must be >= 0, got {sample_time!r}")
    wc = 2 * math.pi * bandwidth
    if sample_time > 0 and wc * sample_time > 0.5:
        raise AcsConfigError(
            f"PID design: bandwidth {bandwidth:g} Hz is too high for sample time "
            f"{sample_time:g} s; expected w_c T <= 0.5"
        )
    phi = math.radians(phase_margin) + 1.5 * wc * sample_time
    if not 0 < phi < math.radians(85):
        raise AcsConfigError(
            f"PID design: phase margin {phase_margin:g} deg plus the sampling lag must be "
            f"within (0, 85) deg"
        )
    b = integral_ratio
    kp = inertia * wc**2 * math.cos(phi)
    ti = b / wc
    td = (math.tan(phi) + 1.0 / b) / wc
    return kp, kp / ti, kp * td


def discrete_loop(inertia: float, kp: float, ki: float, kd: float,
                  sample_time: float) -> control.StateSpace:
    """Sampled loop transfer ``L(z)`` broken at the torque input.

    Plant: ``J theta'' = u`` with ``u`` held over each sample (exact ZOH), sampled
    attitude and rate.  Controller: the law of :mod:`acsfmu.pid` with its one-sample
    delay.  Negative feedback convention: the closed loop is ``L / (1 + L)``.

    Parameters
    ----------
    inertia : float
        Body inertia (kg m^2).
    kp, ki, kd : float
        Parallel PID gains.
    sample_time : float
        Sample time (s).

    Returns
    -------
    control.StateSpace
        Discrete-time SISO ``L(z)`` with ``dt = sample_time``; states attitude,
        rate, integral and delayed torque.
    """
    T, J = sample_time, inertia
    # states: attitude, rate, integral of attitude, delayed controller output
    A = np.array([[1.0, T, 0.0, 0.0],
                  [0.0, 1.0, 0.0, 0.0],
                  [T, 0.0, 1.0, 0.0],
                  [kp, kd, ki, 0.0]])
    B = np.array([[T**2 / (2 * J)], [T / J], [0.0], [0.0]])
    C = np.array([[0.0, 0.0, 0.0, 1.0]])
    import control   # here: python-control costs 0.7 s to import, which a slave never needs

    return control.ss(A, B, C, np.zeros((1, 1)), T)


def _response(loop: control.StateSpace, f) -> np.ndarray:
    """Complex frequency response of the sampled loop at ``f`` (Hz)."""
    return np.asarray(loop(np.exp(2j * np.pi * np.asarray(f) * loop.dt)))


def loop_margins(loop: control.StateSpace) -> tuple[float, float, float]:
    """Crossover, phase margin and upper gain margin of a sampled loop.

    The frequency axis up to Nyquist is swept densely (log grid) and each crossing is
    refined with Brent's method.  The loop must cross 0 dB exactly once.

    Parameters
    ----------
    loop : control.StateSpace
        Discrete SISO loop ``L(z)`` (negative feedback convention).

    Returns
    -------
    crossover : float
        Gain crossover frequency (Hz).
    phase_margin : float
        ``180 + arg L`` at the crossover, wrapped to (-180, 180] (deg).
    gain_margin : float
        ``1 / |L|`` at the first -180 deg phase crossing above the gain crossover
        (dimensionless); ``inf`` if there is none below Nyquist.
    """
    # deferred: scipy takes about 1 s to load
    from scipy.optimize import brentq

    nyquist = 0.5 / loop.dt
    f = np.logspace(math.log10(nyquist) - 7, math.log10(nyquist * 0.9999), 20000)
    resp = _response(loop, f)
    lm = np.log(np.abs(resp))
    idx = np.flatnonzero(np.sign(lm[:-1]) != np.sign(lm[1:]))
    if idx.size != 1:
        raise ValueError(f"loop gain crosses 1 at {idx.size} places; expected exactly one")
    i = int(idx[0])
    fc = brentq(lambda x: math.log(abs(_response(loop, x))), f[i], f[i + 1], xtol=1e-12)
    pm = math.degrees(np.angle(-_response(loop, fc)))
    # phase crossings (Im L = 0 with Re L < 0) above the gain crossover
    above = f > fc
    im = resp.imag[above]
    fa = f[above]
    gm = math.inf
    for j in np.flatnonzero(np.sign(im[:-1]) != np.sign(im[1:])):
        fp = brentq(lambda x: float(_response(loop, x).imag), fa[j], fa[j + 1], xtol=1e-12)
        value = _response(loop, fp)
        if value.real < 0:
            gm = 1.0 / abs(value)
            break
    return float(fc), float(pm), float(gm)


def closed_loop_bandwidth(loop: control.StateSpace) -> float:
    """-3 dB frequency (Hz) of the closed loop ``L / (1 + L)``.

    Parameters
    ----------
    loop : control.StateSpace
        Discrete SISO loop ``L(z)``.

    Returns
    -------
    float
        First frequency where ``|L / (1 + L)|`` drops below ``1/sqrt(2)`` times its
        low-frequency value (Hz); ``inf`` if it does not below Nyquist.
    """
    f = np.logspace(-6, math.log10(0.4999 / loop.dt), 20000)
    resp = _response(loop, f)
    mag = np.abs(resp / (1 + resp))
    below = np.flatnonzero(mag < mag[0] / math.sqrt(2))
    return float(f[below[0]]) if below.size else math.inf


def design_axis(inertia: float, bandwidth: float = 0.1, phase_margin: float = 50.0,
                sample_time: float = 0.1, integral_ratio: float = 5.0) -> AxisDesign:
    """Design one axis and report the sampled loop's margins and bandwidths.

    Parameters
    ----------
    inertia : float
        Body inertia about the axis (kg m^2).
    bandwidth : float
        Desired gain crossover frequency (Hz).
    phase_margin : float
        Desired phase margin (deg).
    sample_time : float
        Controller sample time (s).
    integral_ratio : float
        Integral zero at ``w_c / integral_ratio``.

    Returns
    -------
    AxisDesign
    """
    kp, ki, kd = pid_gains_for(inertia, bandwidth, phase_margin, sample_time, integral_ratio)
    loop = discrete_loop(inertia, kp, ki, kd, sample_time)
    fc, pm, gm = loop_margins(loop)
    return AxisDesign(kp, ki, kd, crossover=fc, phase_margin=pm, gain_margin=gm,
                      bandwidth=closed_loop_bandwidth(loop))


def design_pid(inertia, bandwidth: float = 0.1, phase_margin: float = 50.0,
               sample_time: float = 0.1, integral_ratio: float = 5.0
               ) -> tuple[PidGains, list[AxisDesign]]:
    """Design the three axes.

    Parameters
    ----------
    inertia : array_like, shape (3,)
        Principal inertias ``Ixx, Iyy, Izz`` (kg m^2).
    bandwidth : float
        Desired crossover frequency, same for all axes (Hz).
    phase_margin : float
        Desired phase margin (deg).
    sample_time : float
        Controller sample time (s).
    integral_ratio : float
        Integral zero at ``w_c / integral_ratio``.

    Returns
    -------
    gains : PidGains
        Gains for :class:`acsfmu.pid.AcsConfig`.
    axes : list of AxisDesign, length 3
        Per-axis gains and margins.
    """
    inertia = np.asarray(inertia, dtype=float)
    if inertia.shape != (3,):
        raise AcsConfigError(f"PID design: inertia has shape {inertia.shape}; expected (3,)")
    axes = [design_axis(float(j), bandwidth, phase_margin, sample_time, integral_ratio)
            for j in inertia]
    gains = PidGains(kp=[a.kp for a in axes], ki=[a.ki for a in axes],
                     kd=[a.kd for a in axes])
    return gains, axes
