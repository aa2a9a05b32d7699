"""Windowed peak-to-peak jitter (PLATSIM style).

Definition
----------
The peak-to-peak jitter of a record ``x`` over a window of ``T`` seconds is the largest
range (max − min) found in any window of duration ``T`` placed anywhere in the record::

    J_pp(T) = max_t ( max_{s in [t, t+T]} x(s) − min_{s in [t, t+T]} x(s) )

Window in samples
-----------------
For a record sampled every ``dt`` seconds, ``T`` is rounded to ``m = round(T / dt)``
sample intervals (at least 1) and a window is the *closed* interval ``[t_i, t_i + m dt]``,
i.e. the ``m + 1`` consecutive samples ``x[i], ..., x[i + m]``.  All ``N − m`` window
positions are examined (a sliding window, one sample apart).  With this convention the
sampled window spans exactly ``T`` when ``T`` is a multiple of ``dt``, so analytic results
for continuous signals (a sine: ``2 A sin(pi T / P)`` for ``T <= P / 2``) hold at the samples.

Short records
-------------
A record with fewer than ``m + 1`` samples holds no complete window: by default this raises
:class:`RecordTooShortError`; with ``short="whole"`` the range of the whole record is
returned instead (the jitter over the longest window the record holds).

Cost
----
Running maxima and minima come from :func:`scipy.ndimage.maximum_filter1d` and
:func:`~scipy.ndimage.minimum_filter1d`, which take O(N) time whatever the window length.
:func:`peak_to_peak` takes the largest range in one compiled pass instead
(:mod:`orchestrator.metrics._window`, van Herk / Gil-Werman block maxima, the same
values) when a C compiler
is there and the record is finite.
"""

from __future__ import annotations

import numpy as np

from ._checks import RecordTooShortError, as_record, intervals
from ._window import window_range_max

__all__ = ["peak_to_peak", "peak_to_peak_series", "window_samples"]

_SHORT = ("raise", "whole")


def window_samples(window: float, dt: float) -> int:
    """Samples in one peak-to-peak window: ``round(window / dt) + 1``.

    Parameters
    ----------
    window : float
        Window duration T (s).
    dt : float
        Sample interval (s).

    Returns
    -------
    n : int
        Number of samples in the closed window ``[t, t + T]`` (at least 2).
    """
    return intervals(window, dt) + 1


def peak_to_peak_series(x, dt: float, window: float, *, axis: int = -1) -> np.ndarray:
    """Range (max − min) of every complete window of duration ``window``.

    Parameters
    ----------
    x : array_like, shape (..., n_samples)
        Uniformly sampled record (any unit, e.g. rad), time along ``axis``.
    dt : float
        Sample interval (s).
    window : float
        Window duration T (s); rounded to ``m = round(T / dt)`` sample intervals.
    axis : int
        Time axis of ``x``.

    Returns
    -------
    ranges : ndarray, shape (..., n_samples − m)
        ``ranges[..., i] = max(x[..., i:i+m+1]) − min(x[..., i:i+m+1])`` (unit of ``x``),
        time moved to the last axis.

    Raises
    ------
    RecordTooShortError
        If the record holds fewer than ``m + 1`` samples.
    """
    arr = np.moveaxis(as_record(x), axis, -1)
    n = window_samples(window, dt)
    n_samples = arr.shape[-1]
    if n_samples < n:
        raise RecordTooShortError(
            f"record has {n_samples} samples but a window of {window!r} s at dt = {dt!r} s "
            f"needs {n}; pass short='whole' to peak_to_peak to use the whole record"
        )
    # imported here: scipy.ndimage adds 50 ms to every command's start, and the metrics
    # of a campaign take the compiled pass (peak_to_peak)
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    # maximum_filter1d centres its window: out[j] covers x[j - n//2 : j - n//2 + n].
    # The complete window starting at i is therefore out[i + n//2].
    hi = maximum_filter1d(arr, size=n, axis=-1, mode="nearest")
    lo = minimum_filter1d(arr, size=n, axis=-1, mode="nearest")
    start = n // 2
    stop = start + n_samples - n + 1
    return hi[..., start:stop] - lo[..., start:stop]


def peak_to_peak(x, dt: float, window: float, *, axis: int = -1, short: str = "raise"):
    """Windowed peak-to-peak jitter: the largest range in any window of duration T.

    Parameters
    ----------
    x : array_like, shape (..., n_samples)
        Uniformly sampled record (any unit, e.g. rad), time along ``axis``.
    dt : float
        Sample interval (s).
    window : float
        Window duration T (s); rounded to ``m = round(T / dt)`` sample intervals, a window
        being the ``m + 1`` samples of the closed interval ``[t, t + T]``.
    axis : int
        Time axis of ``x``.
    short : {"raise", "whole"}
        What to do when the record has fewer than ``m + 1`` samples: raise
        :class:`RecordTooShortError`, or return the range of the whole record.

    Returns
    -------
    jitter : float or ndarray, shape (...)
        Peak-to-peak jitter (unit of ``x``), one value per record.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(0, 2, 0.001)
    >>> float(np.round(peak_to_peak(np.sin(2 * np.pi * t), 0.001, 0.1), 6))  # 2 sin(pi/10)
    0.618034
    """
    if short not in _SHORT:
        raise ValueError(f"short is {short!r}; expected one of {_SHORT}")
    arr = np.moveaxis(as_record(x), axis, -1)
    n = window_samples(window, dt)
    if arr.shape[-1] < n:
        if short == "raise":
            raise RecordTooShortError(
                f"record has {arr.shape[-1]} samples but a window of {window!r} s at "
                f"dt = {dt!r} s needs {n}; pass short='whole' to use the whole record"
            )
        out = arr.max(axis=-1) - arr.min(axis=-1)
    else:
        out = window_range_max(arr, n)   # compiled, one pass; the same values
        if out is None:
            out = peak_to_peak_series(arr, dt, window).max(axis=-1)
    return out[()] if out.ndim == 0 else out
