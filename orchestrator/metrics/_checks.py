"""Argument checks shared by the jitter metrics (errors subclass built-ins)."""

from __future__ import annotations

import math

import numpy as np


class RecordTooShortError(ValueError):
    """A record holds fewer samples than one window needs."""


class WindowError(ValueError):
    """A window duration or sample interval is not usable."""


def as_record(x, name: str = "x", min_ndim: int = 1) -> np.ndarray:
    """Return ``x`` as a finite float64 array with at least ``min_ndim`` dimensions.

    Parameters
    ----------
    x : array_like, shape (..., n_samples)
        A record, samples along the last axis; its values keep their own unit.
    name : str
        Name of the record in error messages.
    min_ndim : int
        Smallest accepted number of dimensions.

    Returns
    -------
    ndarray of float64
        ``x``, unchanged in shape.
    """
    arr = np.asarray(x, dtype=float)
    if arr.ndim < min_ndim:
        raise ValueError(f"record {name} has {arr.ndim} dimension(s); expected at least {min_ndim}")
    if arr.shape[-1] == 0:
        raise RecordTooShortError(f"record {name} has no samples; expected at least one")
    if not np.all(np.isfinite(arr)):
        bad = int(np.count_nonzero(~np.isfinite(arr)))
        raise ValueError(f"record {name} has {bad} non-finite value(s); expected finite samples")
    return arr


def check_dt(dt: float) -> float:
    """Return the sample interval ``dt`` (s) as a positive finite float."""
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0.0):
        raise WindowError(f"sample interval dt is {dt!r}; expected a positive finite number of seconds")
    return dt


def intervals(window: float, dt: float, name: str = "window") -> int:
    """Number of sample intervals in a window: ``round(window / dt)``, at least 1.

    Parameters
    ----------
    window : float
        Window duration (s).
    dt : float
        Sample interval (s).
    name : str
        Name of the window used in error messages.

    Returns
    -------
    m : int
        ``round(window / dt)``; the window duration is rounded to the nearest whole
        number of sample intervals.
    """
    dt = check_dt(dt)
    window = float(window)
    if not (math.isfinite(window) and window > 0.0):
        raise WindowError(f"{name} is {window!r} s; expected a positive finite duration")
    m = int(round(window / dt))
    if m < 1:
        raise WindowError(
            f"{name} of {window!r} s is shorter than half the sample interval dt = {dt!r} s; "
            "expected a window of at least one sample interval"
        )
    return m
