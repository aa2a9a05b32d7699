"""RMS windowed jitter and stability of a time record.

Jitter over a window T is the RMS deviation from the window mean; stability over a lag Ts
is the RMS change across Ts.  For a record sampled every ``dt`` seconds a window holds
``m = round(T / dt)`` consecutive samples (the half-open interval ``[t, t + T)``) and the
lag is ``k = round(Ts / dt)`` samples.  Windows slide one sample at a time, so every
complete window of the record contributes:

jitter
    ``J(T)^2 = mean_i [ mean_{j=i}^{i+m-1} (x_j − xbar_i)^2 ]`` with ``xbar_i`` the mean of
    window ``i``; ``J = sqrt(J^2)``.
stability
    ``S(Ts)^2 = mean_i (x_{i+k} − x_i)^2``, or with an averaging window ``T``,
    ``S(Ts, T)^2 = mean_i (xbar_{i+k} − xbar_i)^2`` (the RMS of the PDE).

Their frequency-domain forms are in :mod:`orchestrator.metrics.spectral`.  All sums are
O(N) through cumulative sums of the mean-removed record.
"""

from __future__ import annotations

import numpy as np

from ._checks import RecordTooShortError, as_record, intervals
from .ecss import sliding_means

__all__ = ["jitter_rms", "stability_rms"]


def jitter_rms(x, dt: float, window: float, *, axis: int = -1):
    """RMS jitter: RMS deviation from the window mean, over all sliding windows.

    Parameters
    ----------
    x : array_like, shape (..., n_samples)
        Uniformly sampled record (e.g. rad), time along ``axis``.
    dt : float
        Sample interval (s).
    window : float
        Window duration T (s), ``m = round(T / dt)`` samples.
    axis : int
        Time axis.

    Returns
    -------
    jitter : float or ndarray, shape (...)
        ``sqrt(mean_i mean_{j in W_i} (x_j − xbar_i)^2)`` (unit of ``x``).
    """
    arr = np.moveaxis(as_record(x), axis, -1)
    m = intervals(window, dt)
    n = arr.shape[-1]
    if n < m:
        raise RecordTooShortError(
            f"record has {n} samples but a window of {window!r} s at dt = {dt!r} s needs {m}"
        )
    if m == 1:  # a one-sample window has no deviation from its own mean
        out = np.zeros(arr.shape[:-1])
        return out[()] if out.ndim == 0 else out
    y = arr - arr.mean(axis=-1, keepdims=True)
    zero = np.zeros(y.shape[:-1] + (1,))
    c1 = np.concatenate([zero, np.cumsum(y, axis=-1)], axis=-1)
    c2 = np.concatenate([zero, np.cumsum(y * y, axis=-1)], axis=-1)
    mean = (c1[..., m:] - c1[..., :-m]) / m
    msq = (c2[..., m:] - c2[..., :-m]) / m
    var = np.maximum(msq - mean * mean, 0.0)
    out = np.sqrt(var.mean(axis=-1))
    return out[()] if out.ndim == 0 else out


def stability_rms(x, dt: float, lag: float, *, window: float | None = None, axis: int = -1):
    """RMS stability: RMS change of the signal (or its window mean) across a lag Ts.

    Parameters
    ----------
    x : array_like, shape (..., n_samples)
        Uniformly sampled record (e.g. rad), time along ``axis``.
    dt : float
        Sample interval (s).
    lag : float
        Stability time Ts (s), ``k = round(Ts / dt)`` samples.
    window : float, optional
        Averaging window T (s).  When given, the change of sliding window means
        (``m = round(T / dt)`` samples) is used instead of the change of samples.
    axis : int
        Time axis.

    Returns
    -------
    stability : float or ndarray, shape (...)
        ``sqrt(mean_i (y_{i+k} − y_i)^2)`` with ``y = x`` or the sliding means (unit of ``x``).
    """
    arr = np.moveaxis(as_record(x), axis, -1)
    y = arr if window is None else sliding_means(arr, dt, window)
    k = intervals(lag, dt, "lag")
    if y.shape[-1] <= k:
        raise RecordTooShortError(
            f"record of {arr.shape[-1]} samples is too short for a lag of {lag!r} s at dt = {dt!r} s"
        )
    d = y[..., k:] - y[..., :-k]
    out = np.sqrt(np.mean(d * d, axis=-1))
    return out[()] if out.ndim == 0 else out
