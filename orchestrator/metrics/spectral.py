"""Frequency-domain RMS jitter and stability: one-sided PSD times a window weighting.

Derivation
----------
Let ``x(t)`` be stationary with one-sided PSD ``S(f)`` (unit²/Hz, ``f >= 0``,
``∫ S df = variance + mean²`` with the mean as a DC line).  A linear, time-invariant metric
``y = h * x`` has mean square ``∫ S(f) |H(f)|² df``.

* Window mean over ``T``: ``xbar(t) = (1/T) ∫_t^{t+T} x``, ``|H(f)|² = sinc²(fT)`` with
  ``sinc(u) = sin(πu) / (πu)``.
* Jitter (RMS deviation from the window mean):
  ``(1/T) ∫_W (x − xbar)² = (1/T) ∫_W x² − xbar²``, whose expectation is
  ``∫ S(f) [1 − sinc²(fT)] df``.  Weighting ``W_J(f) = 1 − sinc²(fT)``.
* Stability (change across a lag ``Ts``): ``x(t + Ts) − x(t)`` has
  ``|H(f)|² = |e^{i2πfTs} − 1|² = 2 [1 − cos(2πfTs)] = 4 sin²(πfTs)``.
  Weighting ``W_S(f) = 2 [1 − cos(2πfTs)]``.
* Stability of window means (RMS of the PDE): the cascade of both,
  ``W_S(f) = 2 [1 − cos(2πfTs)] sinc²(fT)``.

Sampled records
---------------
The time-domain metrics of :mod:`orchestrator.metrics.rms` average ``m = round(T/dt)``
samples; their exact kernel is the Fejér form ``[sin(πfmdt) / (m sin(πfdt))]²``, which
replaces ``sinc²(fT)`` when ``dt`` is passed to the weighting functions.  The two differ by
less than ``1/m²`` below the Nyquist frequency.  The lag weighting is exact for sampled
records when ``Ts`` is a whole number of samples.
"""

from __future__ import annotations

import numpy as np

from ._checks import as_record, check_dt, intervals

__all__ = [
    "average_weight",
    "jitter_rms_from_frf",
    "jitter_rms_from_psd",
    "jitter_weight",
    "one_sided_psd",
    "response_psd",
    "rms_from_psd",
    "stability_rms_from_psd",
    "stability_weight",
]


def _freq(f) -> np.ndarray:
    f = np.asarray(f, dtype=float)
    if f.ndim != 1 or f.size < 2:
        raise ValueError(f"frequency grid f has shape {f.shape}; expected (n_f,) with n_f >= 2")
    if np.any(f < 0) or np.any(np.diff(f) <= 0):
        raise ValueError("frequency grid f must be non-negative and strictly increasing (Hz)")
    return f


def average_weight(f, window: float, dt: float | None = None) -> np.ndarray:
    """Squared gain of a moving average over ``window``: ``sinc²(f T)``.

    Parameters
    ----------
    f : array_like, shape (n_f,)
        Frequencies (Hz).
    window : float
        Averaging window T (s).
    dt : float, optional
        Sample interval (s); if given, the exact kernel of an ``m = round(T/dt)``-sample
        average, ``[sin(π f m dt) / (m sin(π f dt))]²``.

    Returns
    -------
    w : ndarray, shape (n_f,)
        Weighting (dimensionless, 1 at f = 0).
    """
    f = np.asarray(f, dtype=float)
    if dt is None:
        return np.sinc(f * float(window)) ** 2
    m = intervals(window, dt)
    num = np.sin(np.pi * f * m * dt)
    den = m * np.sin(np.pi * f * dt)
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(np.abs(den) > 1e-300, (num / np.where(den == 0, 1, den)) ** 2, 1.0)
    return w


def jitter_weight(f, window: float, dt: float | None = None) -> np.ndarray:
    """Jitter weighting ``1 − sinc²(f T)``.

    Parameters
    ----------
    f : array_like, shape (n_f,)
        Frequencies (Hz).
    window : float
        Jitter window T (s).
    dt : float, optional
        Sample interval (s) for the exact sampled kernel (see :func:`average_weight`).

    Returns
    -------
    w : ndarray, shape (n_f,)
        Weighting (dimensionless, 0 at f = 0, tends to 1 for f >> 1/T).
    """
    return 1.0 - average_weight(f, window, dt)


def stability_weight(f, lag: float, window: float | None = None, dt: float | None = None):
    """Stability weighting ``2 [1 − cos(2π f Ts)]`` (times ``sinc²(f T)`` with a window).

    Parameters
    ----------
    f : array_like, shape (n_f,)
        Frequencies (Hz).
    lag : float
        Stability time Ts (s).
    window : float, optional
        Averaging window T (s) of the two means being compared.
    dt : float, optional
        Sample interval (s) for the exact sampled averaging kernel.

    Returns
    -------
    w : ndarray, shape (n_f,)
        Weighting (dimensionless, between 0 and 4).
    """
    f = np.asarray(f, dtype=float)
    w = 2.0 * (1.0 - np.cos(2.0 * np.pi * f * float(lag)))
    if window is not None:
        w = w * average_weight(f, window, dt)
    return w


def rms_from_psd(f, psd, weight=None) -> np.ndarray | float:
    """RMS of a weighted one-sided PSD: ``sqrt(∫ S(f) w(f) df)`` (trapezoid rule).

    Parameters
    ----------
    f : array_like, shape (n_f,)
        Frequencies (Hz), non-negative and increasing.
    psd : array_like, shape (n_f,) or (n_f, n_channels)
        One-sided PSD (unit²/Hz).
    weight : array_like, shape (n_f,), optional
        Weighting function (dimensionless); 1 if omitted.

    Returns
    -------
    rms : float or ndarray, shape (n_channels,)
        RMS value (unit).
    """
    f = _freq(f)
    s = np.asarray(psd, dtype=float)
    if s.shape[0] != f.size:
        raise ValueError(f"psd has {s.shape[0]} frequency rows; expected {f.size} to match f")
    w = np.ones_like(f) if weight is None else np.asarray(weight, dtype=float)
    w = w.reshape((f.size,) + (1,) * (s.ndim - 1))
    out = np.sqrt(np.maximum(np.trapezoid(s * w, f, axis=0), 0.0))
    return out[()] if np.ndim(out) == 0 else out


def jitter_rms_from_psd(f, psd, window: float, dt: float | None = None):
    """RMS jitter over a window T from a one-sided PSD: ``sqrt(∫ S (1 − sinc²(fT)) df)``.

    Parameters
    ----------
    f : array_like, shape (n_f,)
        Frequencies (Hz).
    psd : array_like, shape (n_f,) or (n_f, n_channels)
        One-sided PSD (unit²/Hz).
    window : float
        Jitter window T (s).
    dt : float, optional
        Sample interval (s) for the exact sampled kernel.

    Returns
    -------
    jitter : float or ndarray, shape (n_channels,)
        RMS jitter (unit).
    """
    return rms_from_psd(f, psd, jitter_weight(f, window, dt))


def stability_rms_from_psd(f, psd, lag: float, window: float | None = None, dt=None):
    """RMS stability over Ts from a one-sided PSD: ``sqrt(∫ S 2(1 − cos 2πfTs) df)``.

    Parameters
    ----------
    f : array_like, shape (n_f,)
        Frequencies (Hz).
    psd : array_like, shape (n_f,) or (n_f, n_channels)
        One-sided PSD (unit²/Hz).
    lag : float
        Stability time Ts (s).
    window : float, optional
        Averaging window T (s) of the means compared (adds ``sinc²(fT)``).
    dt : float, optional
        Sample interval (s) for the exact sampled averaging kernel.

    Returns
    -------
    stability : float or ndarray, shape (n_channels,)
        RMS stability (unit).
    """
    return rms_from_psd(f, psd, stability_weight(f, lag, window, dt))


def response_psd(frf, disturbance_psd) -> np.ndarray:
    """One-sided output PSD of an FRF driven by a disturbance PSD.

    Parameters
    ----------
    frf : array_like of complex, shape (n_f,) or (n_f, n_out, n_in)
        Frequency response from disturbance to output (output unit per disturbance unit).
    disturbance_psd : array_like, shape (n_f,), (n_f, n_in) or (n_f, n_in, n_in)
        One-sided disturbance PSD (unit²/Hz): one input, uncorrelated inputs (auto-spectra
        only), or a full cross-spectral density matrix.

    Returns
    -------
    psd : ndarray, shape (n_f,) or (n_f, n_out)
        Output auto-spectra ``diag(H S H^H)`` (output unit²/Hz).
    """
    h = np.asarray(frf)
    s = np.asarray(disturbance_psd)
    if h.ndim == 1:
        if s.shape != h.shape:
            raise ValueError(f"disturbance PSD has shape {s.shape}; expected {h.shape} like frf")
        return np.abs(h) ** 2 * s.real
    if h.ndim != 3:
        raise ValueError(f"frf has shape {h.shape}; expected (n_f,) or (n_f, n_out, n_in)")
    n_f, _, n_in = h.shape
    if s.shape == (n_f, n_in):
        return np.einsum("fok,fk->fo", np.abs(h) ** 2, s.real)
    if s.shape == (n_f, n_in, n_in):
        return np.einsum("fok,fkl,fol->fo", h, s, h.conj()).real
    raise ValueError(
        f"disturbance PSD has shape {s.shape}; expected ({n_f}, {n_in}) or ({n_f}, {n_in}, {n_in})"
    )


def jitter_rms_from_frf(f, frf, disturbance_psd, window: float, dt: float | None = None):
    """RMS jitter of the response of an FRF to a disturbance PSD.

    Parameters
    ----------
    f : array_like, shape (n_f,)
        Frequencies (Hz).
    frf : array_like of complex, shape (n_f,) or (n_f, n_out, n_in)
        Frequency response (output unit per disturbance unit).
    disturbance_psd : array_like, shape (n_f,), (n_f, n_in) or (n_f, n_in, n_in)
        One-sided disturbance PSD (disturbance unit²/Hz).
    window : float
        Jitter window T (s).
    dt : float, optional
        Sample interval (s) for the exact sampled kernel.

    Returns
    -------
    jitter : float or ndarray, shape (n_out,)
        RMS jitter of each output (output unit).
    """
    return jitter_rms_from_psd(f, response_psd(frf, disturbance_psd), window, dt)


def one_sided_psd(x, dt: float, segment: float, *, axis: int = -1):
    """One-sided PSD estimate of a record (Welch, Hann window, 50 % overlap).

    Parameters
    ----------
    x : array_like, shape (..., n_samples)
        Uniformly sampled record (unit), time along ``axis``.
    dt : float
        Sample interval (s).
    segment : float
        Segment duration (s); sets the resolution ``1 / segment`` (Hz).
    axis : int
        Time axis.

    Returns
    -------
    f : ndarray, shape (n_f,)
        Frequencies from 0 to the Nyquist frequency (Hz).
    psd : ndarray, shape (n_f, ...)
        One-sided PSD (unit²/Hz), frequency first; the mean is removed per segment.
    """
    arr = np.moveaxis(as_record(x), axis, -1)
    dt = check_dt(dt)
    nper = min(intervals(segment, dt, "segment"), arr.shape[-1])
    from scipy.signal import welch   # imported here: scipy.signal takes ~1 s to import

    f, p = welch(arr, fs=1.0 / dt, nperseg=nper, detrend="constant", axis=-1)
    return f, np.moveaxis(p, -1, 0)
