"""A campaign's metric kinds on records: one dispatch for cases, sweeps and samples."""

from __future__ import annotations

import numpy as np

from . import ecss
from .peak import peak_to_peak
from .rms import jitter_rms, stability_rms

__all__ = ["metric_values", "skip_start"]


def skip_start(t0: float, skip: float, dt: float) -> float:
    """The first time a campaign's metrics read: ``t0 + skip``, less half a sample so
    that the sample at that time is kept whatever its round-off.

    Parameters
    ----------
    t0 : float
        Time of the record's first sample (s).
    skip : float
        Transient the metrics leave out (s).
    dt : float
        Sample interval of the record (s).

    Returns
    -------
    float
        The samples at or after it are the ones the metrics read.
    """
    return t0 + skip - 0.5 * dt


def metric_values(x, dt: float, metrics) -> np.ndarray:
    """The metrics of records ``x``, time last.

    Parameters
    ----------
    x : array_like, shape (..., n_samples)
        Records (e.g. a line of sight in rad).
    dt : float
        Sample interval (s).
    metrics : sequence of (str, float or None)
        ``(kind, window)``: ``peak_to_peak`` (window T, the whole record when shorter),
        ``rms_jitter`` (window T), ``stability`` (lag), ``rms`` (about the record mean),
        and the ECSS indices ``ape`` (largest ``|e|``), ``mpe``, ``rpe``, ``pde``
        (window T; :data:`orchestrator.campaign.spec.METRIC_KINDS`).

    Returns
    -------
    ndarray, shape (..., n_metrics)
        In the unit of ``x``.
    """
    x = np.asarray(x, dtype=float)
    out = []
    for kind, w in metrics:
        if kind == "peak_to_peak":
            v = peak_to_peak(x, dt, w, short="whole")
        elif kind == "rms_jitter":
            v = jitter_rms(x, dt, w)
        elif kind == "stability":
            v = stability_rms(x, dt, w)
        elif kind == "ape":
            v = np.max(np.abs(ecss.ape(x)), axis=-1)
        elif kind == "mpe":
            v = np.max(np.abs(ecss.mpe(x, dt, w)), axis=-1)
        elif kind == "rpe":
            v = np.max(np.abs(ecss.rpe(x, dt, w)), axis=-1)
        elif kind == "pde":
            v = np.max(np.abs(ecss.pde(x, dt, w, w)), axis=-1)
        elif kind == "rms":
            v = np.std(x, axis=-1)
        else:
            raise ValueError(f"metric kind {kind!r} is unknown; see "
                             "orchestrator.campaign.spec.METRIC_KINDS")
        out.append(np.asarray(v, float))
    return np.stack(out, axis=-1)
