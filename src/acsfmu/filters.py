"""Second-order filters of the ACS, discretised by Tustin with prewarping (pure, SI).

Every filter is one biquad in powers of ``s / w`` (``w = 2 pi f``)::

    H(s) = (n2 (s/w)^2 + n1 (s/w) + n0) / (d2 (s/w)^2 + d1 (s/w) + d0)

    notch      n = (1, 2 zeta_num, 1),  d = (1, 2 zeta_den, 1)
    low-pass   n = (0, 0, 1),           d = (1, 2 zeta, 1)

Tustin prewarped at ``w`` substitutes ``s / w = c (z - 1) / (z + 1)`` with
``c = 1 / tan(w T / 2)``, so the discrete response at ``e^{j w T}`` equals ``H(j w)``
exactly (a notch keeps its depth ``zeta_num / zeta_den`` at its centre).  Coefficients
``[b0, b1, b2, a1, a2]`` (``a0 = 1``) run in direct form II transposed::

    y   = b0 x + s1
    s1' = b1 x - a1 y + s2
    s2' = b2 x - a2 y

The native kernel (``nativefmu/csrc/acs.c``) computes the same coefficients with the
same formulas in the same order, so both builds agree bit for bit.

:class:`AcsFilters` is the filter set of the controller: per axis a notch and a
low-pass on the commanded torque, and one anti-alias low-pass on each of the six inputs
(roll, pitch, yaw, rate_x, rate_y, rate_z).  A frequency of 0 switches a filter off.
The anti-alias filter is digital, at the controller's rate: it filters the samples the
controller takes and cannot remove what aliased before sampling.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["AXES", "AcsConfigError", "AcsFilters", "biquad_state_space", "biquad_step",
           "lowpass_biquad", "notch_biquad", "per_axis", "prewarped_biquad"]

#: Body axes, in the order of every per-axis array.
AXES = ("x", "y", "z")
#: Coefficients of a filter that passes its input unchanged.
IDENTITY = (1.0, 0.0, 0.0, 0.0, 0.0)


class AcsConfigError(ValueError):
    """ACS parameters are inconsistent (wrong shape, sign or value)."""


def per_axis(value, owner: str, name: str, positive: bool = False) -> np.ndarray:
    """Three finite numbers, one per body axis (a scalar applies to all three).

    Parameters
    ----------
    value : array_like, shape (3,) or scalar
        The values.
    owner : str
        What the values belong to, for the error message.
    name : str
        Parameter name, for the error message.
    positive : bool
        Require every value to be positive.

    Returns
    -------
    ndarray, shape (3,)
        Read-only copy.
    """
    v = np.broadcast_to(np.asarray(value, dtype=float), (3,)).copy() \
        if np.ndim(value) == 0 else np.asarray(value, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise AcsConfigError(f"{owner}: {name} must be 3 finite numbers, got {value!r}")
    if positive and np.any(v <= 0):
        raise AcsConfigError(f"{owner}: {name} must be positive, got {value!r}")
    v.flags.writeable = False
    return v


def prewarped_biquad(num, den, freq_hz: float, sample_time: float) -> np.ndarray:
    """Tustin discretisation of a biquad in ``s / w``, prewarped at ``w``.

    Parameters
    ----------
    num : sequence of float, length 3
        ``(n2, n1, n0)``: numerator coefficients of ``(s/w)^2, s/w, 1``.
    den : sequence of float, length 3
        ``(d2, d1, d0)``: denominator coefficients, likewise.
    freq_hz : float
        Prewarping (and scaling) frequency ``f``, ``w = 2 pi f`` (Hz); positive and below
        the Nyquist frequency ``0.5 / T``.
    sample_time : float
        Sample time ``T`` (s).

    Returns
    -------
    ndarray, shape (5,)
        ``[b0, b1, b2, a1, a2]`` of ``(b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)``.
    """
    w = 2.0 * math.pi * freq_hz
    c = 1.0 / math.tan(0.5 * w * sample_time)
    c2 = c * c
    n2, n1, n0 = (float(v) for v in num)
    d2, d1, d0 = (float(v) for v in den)
    a0 = d2 * c2 + d1 * c + d0
    return np.array([(n2 * c2 + n1 * c + n0) / a0, 2.0 * (n0 - n2 * c2) / a0,
                     (n2 * c2 - n1 * c + n0) / a0, 2.0 * (d0 - d2 * c2) / a0,
                     (d2 * c2 - d1 * c + d0) / a0])


def notch_biquad(freq_hz: float, zeta_num: float, zeta_den: float,
                 sample_time: float) -> np.ndarray:
    """Notch ``(s^2 + 2 zn w s + w^2) / (s^2 + 2 zd w s + w^2)``, Tustin prewarped at ``w``.

    Parameters
    ----------
    freq_hz : float
        Centre frequency (Hz).
    zeta_num : float
        Numerator damping ``zn``; the depth at the centre is ``zn / zd``.
    zeta_den : float
        Denominator damping ``zd`` (sets the width).
    sample_time : float
        Sample time (s).

    Returns
    -------
    ndarray, shape (5,)
        ``[b0, b1, b2, a1, a2]``.
    """
    return prewarped_biquad((1.0, 2.0 * zeta_num, 1.0), (1.0, 2.0 * zeta_den, 1.0),
                            freq_hz, sample_time)


def lowpass_biquad(freq_hz: float, zeta: float, sample_time: float) -> np.ndarray:
    """Low-pass ``w^2 / (s^2 + 2 zeta w s + w^2)``, Tustin prewarped at ``w``.

    Parameters
    ----------
    freq_hz : float
        Corner frequency (Hz).
    zeta : float
        Damping ratio.
    sample_time : float
        Sample time (s).

    Returns
    -------
    ndarray, shape (5,)
        ``[b0, b1, b2, a1, a2]``.
    """
    return prewarped_biquad((0.0, 0.0, 1.0), (1.0, 2.0 * zeta, 1.0), freq_hz, sample_time)


def biquad_step(coef, x, s, on=True):
    """One sample of biquads in direct form II transposed (elementwise).

    Parameters
    ----------
    coef : ndarray, shape (..., 5)
        ``[b0, b1, b2, a1, a2]`` per filter.
    x : ndarray, shape (...)
        Input sample per filter.
    s : ndarray, shape (..., 2)
        States ``(s1, s2)`` per filter.
    on : bool or ndarray of bool, shape (...)
        Filters switched on; the others pass ``x`` unchanged and keep their states.

    Returns
    -------
    y : ndarray, shape (...)
        Output sample.
    s : ndarray, shape (..., 2)
        New states.
    """
    coef = np.asarray(coef, dtype=float)
    x = np.asarray(x, dtype=float)
    b0, b1, b2, a1, a2 = np.moveaxis(coef, -1, 0)
    y = b0 * x + s[..., 0]
    new = np.stack([b1 * x - a1 * y + s[..., 1], b2 * x - a2 * y], axis=-1)
    on = np.asarray(on, dtype=bool)
    return np.where(on, y, x), np.where(on[..., None], new, s)


def biquad_state_space(coef) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """State-space form of a biquad in direct form II transposed.

    With the state ``s = (s1, s2)`` of :func:`biquad_step`: ``s' = A s + B x``,
    ``y = C s + D x``.

    Parameters
    ----------
    coef : array_like, shape (5,)
        ``[b0, b1, b2, a1, a2]``.

    Returns
    -------
    A : ndarray, shape (2, 2)
    B : ndarray, shape (2,)
    C : ndarray, shape (2,)
    D : float
    """
    b0, b1, b2, a1, a2 = (float(c) for c in coef)
    return (np.array([[-a1, 1.0], [-a2, 0.0]]), np.array([b1 - a1 * b0, b2 - a2 * b0]),
            np.array([1.0, 0.0]), b0)


def _corner(owner: str, name: str, value: float, sample_time: float) -> None:
    nyquist = 0.5 / sample_time
    if math.isfinite(value) and 0.0 <= value < nyquist:
        return
    if value < 0:
        why = ("is negative; expected 0 (off) or a corner below the Nyquist frequency "
               f"{nyquist:g} Hz")
    elif math.isnan(value):
        why = f"is not a frequency; expected one below the Nyquist frequency {nyquist:g} Hz"
    else:
        why = (f"is at or above the Nyquist frequency {nyquist:g} Hz of sample time "
               f"{sample_time:g} s")
    raise AcsConfigError(f"{owner}: {name} = {value:g} Hz {why}")


def _damping(owner: str, name: str, value: float, sample_time: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise AcsConfigError(f"{owner}: {name} = {value:g} is not a positive damping ratio "
                             f"(filters sampled below the Nyquist frequency "
                             f"{0.5 / sample_time:g} Hz)")


def _three(owner: str, name: str, value) -> np.ndarray:
    v = np.asarray(value, dtype=float)
    v = np.broadcast_to(v, (3,)).copy() if v.ndim == 0 else v.copy()
    if v.shape != (3,):
        raise AcsConfigError(f"{owner}: {name} must be 3 numbers (x, y, z), got {value!r}")
    return v


@dataclass(frozen=True, eq=False)
class AcsFilters:
    """Filter set of the ACS: notch and low-pass on the torque, anti-alias on the inputs.

    All filters are off by default (frequency 0).  Every damping must be positive and
    every corner non-negative and below the Nyquist frequency ``0.5 / sample_time``.

    Parameters
    ----------
    sample_time : float
        Controller sample time ``T`` the filters run at (s).
    notch_hz : array_like, shape (3,) or scalar
        Notch centre per axis on the commanded torque (Hz); 0 for none.
    notch_zeta_num : array_like, shape (3,) or scalar
        Notch numerator damping per axis (dimensionless).
    notch_zeta_den : array_like, shape (3,) or scalar
        Notch denominator damping per axis (dimensionless).
    lowpass_hz : array_like, shape (3,) or scalar
        Low-pass corner per axis after the notch (Hz); 0 for none.
    lowpass_zeta : array_like, shape (3,) or scalar
        Low-pass damping per axis (dimensionless).
    antialias_hz : float
        Low-pass corner on each of the six inputs (Hz); 0 for none.
    antialias_zeta : float
        Its damping (dimensionless).

    Attributes
    ----------
    notch, lowpass : ndarray, shape (3, 5)
        Coefficients ``[b0, b1, b2, a1, a2]`` per axis (identity where off).
    antialias : ndarray, shape (5,)
        Coefficients of the input filter (identity where off).
    """

    sample_time: float = 0.1
    notch_hz: np.ndarray = 0.0
    notch_zeta_num: np.ndarray = 0.05
    notch_zeta_den: np.ndarray = 0.5
    lowpass_hz: np.ndarray = 0.0
    lowpass_zeta: np.ndarray = 0.7
    antialias_hz: float = 0.0
    antialias_zeta: float = 0.7
    notch: np.ndarray = field(init=False, repr=False)
    lowpass: np.ndarray = field(init=False, repr=False)
    antialias: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        owner, T = "ACS filters", self.sample_time
        if not (isinstance(T, (int, float)) and math.isfinite(T) and T > 0):
            raise AcsConfigError(f"{owner}: sample_time must be a positive number, got {T!r}")
        names = ("notch_hz", "notch_zeta_num", "notch_zeta_den", "lowpass_hz", "lowpass_zeta")
        v = {n: _three(owner, n, getattr(self, n)) for n in names}
        for i, axis in enumerate(AXES):   # the native kernel checks in this order too
            for n in names:
                check = _corner if n.endswith("_hz") else _damping
                check(owner, f"{n}_{axis}", float(v[n][i]), T)
        for n in ("antialias_hz", "antialias_zeta"):
            value = getattr(self, n)
            if not isinstance(value, (int, float)):
                raise AcsConfigError(f"{owner}: {n} must be a number, got {value!r}")
            (_corner if n.endswith("_hz") else _damping)(owner, n, float(value), T)
            object.__setattr__(self, n, float(value))
        for n in names:
            v[n].flags.writeable = False
            object.__setattr__(self, n, v[n])
        notch = np.array([notch_biquad(v["notch_hz"][i], v["notch_zeta_num"][i],
                                       v["notch_zeta_den"][i], T)
                          if v["notch_hz"][i] > 0 else IDENTITY for i in range(3)])
        low = np.array([lowpass_biquad(v["lowpass_hz"][i], v["lowpass_zeta"][i], T)
                        if v["lowpass_hz"][i] > 0 else IDENTITY for i in range(3)])
        aa = np.array(lowpass_biquad(self.antialias_hz, self.antialias_zeta, T)
                      if self.antialias_hz > 0 else IDENTITY)
        for n, c in (("notch", notch), ("lowpass", low), ("antialias", aa)):
            c.flags.writeable = False
            object.__setattr__(self, n, c)

    @property
    def notch_on(self) -> np.ndarray:
        """Axes with a notch, shape (3,)."""
        return self.notch_hz > 0

    @property
    def lowpass_on(self) -> np.ndarray:
        """Axes with a low-pass on the torque, shape (3,)."""
        return self.lowpass_hz > 0

    @property
    def antialias_on(self) -> bool:
        """Whether the six inputs are filtered."""
        return self.antialias_hz > 0

    @property
    def any_on(self) -> bool:
        """Whether any filter is switched on."""
        return bool(self.antialias_on or np.any(self.notch_on) or np.any(self.lowpass_on))
