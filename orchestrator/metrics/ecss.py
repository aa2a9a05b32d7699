"""ECSS-E-ST-60-10C pointing error indices and statistical requirement checks.

Indices of an error signal ``e(t)`` for a window of duration ``Δt``:

APE
    Absolute performance error, ``APE(t) = e(t)``.
MPE
    Mean performance error, the mean of ``e`` over one window: ``MPE_k = mean(e over W_k)``.
RPE
    Relative performance error, ``RPE(t, Δt) = e(t) − MPE_k`` for the window ``W_k``
    that contains ``t``.
PDE
    Performance drift error, the difference between two window means ``Ts`` apart within
    one observation: ``PDE(t) = mean(e over [t + Ts, t + Ts + Δt)) − mean(e over [t, t + Δt))``.

Windows in samples
------------------
For samples every ``dt`` seconds a window of ``Δt`` holds ``m = round(Δt / dt)`` samples
(the half-open interval ``[t, t + Δt)``, so the window mean is the rectangle-rule time
average).  MPE and RPE use consecutive, non-overlapping windows starting at the first sample
(``W_k`` = samples ``k m ... k m + m − 1``), so the window containing ``t`` is unique; the
trailing ``n_samples mod m`` samples that do not fill a window are dropped.  PDE uses
sliding windows (one sample apart) and a separation of ``k = round(Ts / dt)`` samples.

Requirements
------------
A requirement reads ``prob(|X| < Xmax) >= Pc`` (``X`` any of the indices).  For an array of
shape ``(n_realisations, n_samples)`` (rows are realisations of the system — e.g. Monte
Carlo runs or units — and columns are time samples) the statistical interpretations are:

temporal
    For every realisation, the fraction of time with ``|X| < Xmax``; the achieved
    probability is the worst (smallest) of these fractions.
ensemble
    The fraction of realisations that meet ``|X| < Xmax`` at *all* times.
mixed
    The fraction of all (realisation, time) pairs with ``|X| < Xmax``: a random time in a
    random realisation.

The requirement passes when the achieved probability is ``>= Pc``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._checks import RecordTooShortError, as_record, intervals

__all__ = [
    "INTERPRETATIONS",
    "RequirementCheck",
    "ape",
    "check_requirement",
    "mpe",
    "pde",
    "rpe",
    "sliding_means",
]

INTERPRETATIONS = ("temporal", "ensemble", "mixed")


def _blocks(e, dt, window, axis):
    arr = np.moveaxis(as_record(e, "e"), axis, -1)
    m = intervals(window, dt, "window")
    n_win = arr.shape[-1] // m
    if n_win == 0:
        raise RecordTooShortError(
            f"error record e has {arr.shape[-1]} samples but a window of {window!r} s at "
            f"dt = {dt!r} s needs {m}"
        )
    return arr[..., : n_win * m].reshape(arr.shape[:-1] + (n_win, m))


def ape(e, *, axis: int = -1) -> np.ndarray:
    """Absolute performance error: the error signal itself.

    Parameters
    ----------
    e : array_like, shape (..., n_samples)
        Pointing error (rad, or any unit).
    axis : int
        Time axis.

    Returns
    -------
    ape : ndarray, shape (..., n_samples)
        ``e`` with time on the last axis (unit of ``e``).
    """
    return np.moveaxis(as_record(e, "e"), axis, -1).copy()


def mpe(e, dt: float, window: float, *, axis: int = -1) -> np.ndarray:
    """Mean performance error: the mean of ``e`` in each consecutive window.

    Parameters
    ----------
    e : array_like, shape (..., n_samples)
        Pointing error (unit of your choice), time along ``axis``.
    dt : float
        Sample interval (s).
    window : float
        Window duration Δt (s), rounded to ``m = round(Δt / dt)`` samples.
    axis : int
        Time axis.

    Returns
    -------
    mpe : ndarray, shape (..., n_samples // m)
        Window means (unit of ``e``); window ``k`` holds samples ``k m ... k m + m − 1``.
    """
    return _blocks(e, dt, window, axis).mean(axis=-1)


def rpe(e, dt: float, window: float, *, axis: int = -1) -> np.ndarray:
    """Relative performance error: ``e(t)`` minus the mean of its window.

    Parameters
    ----------
    e : array_like, shape (..., n_samples)
        Pointing error, time along ``axis``.
    dt : float
        Sample interval (s).
    window : float
        Window duration Δt (s), rounded to ``m = round(Δt / dt)`` samples.
    axis : int
        Time axis.

    Returns
    -------
    rpe : ndarray, shape (..., (n_samples // m) * m)
        ``e[..., j] − MPE_k`` with ``k = j // m`` (unit of ``e``); the trailing samples that
        do not fill a window are dropped.
    """
    b = _blocks(e, dt, window, axis)
    out = b - b.mean(axis=-1, keepdims=True)
    return out.reshape(out.shape[:-2] + (-1,))


def sliding_means(e, dt: float, window: float, *, axis: int = -1) -> np.ndarray:
    """Mean of ``e`` over every window of ``m = round(Δt / dt)`` consecutive samples.

    Parameters
    ----------
    e : array_like, shape (..., n_samples)
        Signal, time along ``axis``.
    dt : float
        Sample interval (s).
    window : float
        Window duration Δt (s).
    axis : int
        Time axis.

    Returns
    -------
    means : ndarray, shape (..., n_samples − m + 1)
        ``means[..., i] = mean(e[..., i:i+m])``; O(N) through a cumulative sum.
    """
    arr = np.moveaxis(as_record(e, "e"), axis, -1)
    m = intervals(window, dt, "window")
    if arr.shape[-1] < m:
        raise RecordTooShortError(
            f"record e has {arr.shape[-1]} samples but a window of {window!r} s at "
            f"dt = {dt!r} s needs {m}"
        )
    ref = arr.mean(axis=-1, keepdims=True)  # remove the mean to keep the cumsum accurate
    c = np.cumsum(arr - ref, axis=-1)
    c = np.concatenate([np.zeros(c.shape[:-1] + (1,)), c], axis=-1)
    return (c[..., m:] - c[..., :-m]) / m + ref


def pde(e, dt: float, window: float, separation: float, *, axis: int = -1) -> np.ndarray:
    """Performance drift error: change of the window mean over a separation Ts.

    Parameters
    ----------
    e : array_like, shape (..., n_samples)
        Pointing error, time along ``axis``.
    dt : float
        Sample interval (s).
    window : float
        Averaging window Δt (s), ``m = round(Δt / dt)`` samples.
    separation : float
        Time Ts between the starts of the two windows (s), ``k = round(Ts / dt)`` samples.
    axis : int
        Time axis.

    Returns
    -------
    pde : ndarray, shape (..., n_samples − m − k + 1)
        ``mean(e[i+k : i+k+m]) − mean(e[i : i+m])`` for every start ``i`` (unit of ``e``).
    """
    means = sliding_means(e, dt, window, axis=axis)
    k = intervals(separation, dt, "separation")
    if means.shape[-1] <= k:
        raise RecordTooShortError(
            f"record e is too short for two windows of {window!r} s separated by "
            f"{separation!r} s at dt = {dt!r} s"
        )
    return means[..., k:] - means[..., :-k]


@dataclass(frozen=True)
class RequirementCheck:
    """Outcome of ``prob(|X| < Xmax) >= Pc`` under one statistical interpretation.

    Attributes
    ----------
    probability : float
        Achieved probability (fraction in [0, 1]).
    confidence : float
        Required probability Pc.
    passed : bool
        ``probability >= confidence``.
    interpretation : str
        "temporal", "ensemble" or "mixed".
    xmax : float
        Requirement bound (unit of X).
    """

    probability: float
    confidence: float
    passed: bool
    interpretation: str
    xmax: float

    def __iter__(self):
        return iter((self.passed, self.probability))


def check_requirement(
    x, xmax: float, confidence: float, interpretation: str = "temporal", *, absolute: bool = True
) -> RequirementCheck:
    """Check ``prob(|X| < Xmax) >= Pc`` under a statistical interpretation.

    Parameters
    ----------
    x : array_like, shape (n_realisations, n_samples) or (n_samples,)
        Index values (e.g. APE or RPE samples); rows are realisations, columns time samples.
        A 1-D array is one realisation.
    xmax : float
        Bound Xmax (unit of ``x``).
    confidence : float
        Required probability Pc in (0, 1].
    interpretation : {"temporal", "ensemble", "mixed"}
        Temporal: worst realisation's fraction of time within bound. Ensemble: fraction of
        realisations within bound at all times. Mixed: fraction of all (realisation, time)
        pairs within bound.
    absolute : bool
        Compare ``|X|`` (default) or the signed ``X`` with ``Xmax``.

    Returns
    -------
    check : RequirementCheck
        Unpacks as ``passed, probability``.
    """
    arr = as_record(x, "x")
    if arr.ndim == 1:
        arr = arr[np.newaxis, :]
    if arr.ndim != 2:
        raise ValueError(
            f"x has shape {arr.shape}; expected (n_realisations, n_samples) or (n_samples,)"
        )
    if not 0.0 < confidence <= 1.0:
        raise ValueError(f"confidence Pc is {confidence!r}; expected a probability in (0, 1]")
    if interpretation not in INTERPRETATIONS:
        raise ValueError(f"interpretation is {interpretation!r}; expected one of {INTERPRETATIONS}")
    ok = (np.abs(arr) if absolute else arr) < xmax
    if interpretation == "temporal":
        p = float(ok.mean(axis=1).min())
    elif interpretation == "ensemble":
        p = float(ok.all(axis=1).mean())
    else:
        p = float(ok.mean())
    return RequirementCheck(p, float(confidence), p >= confidence, interpretation, float(xmax))
