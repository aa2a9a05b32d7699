"""Pointing jitter metrics on sampled records and spectra (pure numpy/scipy).

One module per concept:

* :mod:`~orchestrator.metrics.peak` — windowed peak-to-peak jitter (PLATSIM style);
* :mod:`~orchestrator.metrics.ecss` — ECSS-E-ST-60-10C indices (APE, MPE, RPE, PDE) and
  ``prob(X < Xmax) >= Pc`` checks (temporal, ensemble, mixed);
* :mod:`~orchestrator.metrics.rms` — RMS windowed jitter and stability in the time domain;
* :mod:`~orchestrator.metrics.spectral` — the same from a one-sided PSD or FRF × PSD;
* :mod:`~orchestrator.metrics.budget` — RSS across events, margins, dominant events;
* :mod:`~orchestrator.metrics.kinds` — a campaign's metric kinds on records, one dispatch.

Records are arrays with time on the last axis, sampled every ``dt`` seconds; durations are
seconds; values keep the unit of the record (rad in the core, arcsec at the edges).
"""

from ._checks import RecordTooShortError, WindowError
from .budget import BudgetLine, Contribution, budget, margin, rss
from .ecss import (
    INTERPRETATIONS,
    RequirementCheck,
    ape,
    check_requirement,
    mpe,
    pde,
    rpe,
    sliding_means,
)
from .kinds import metric_values, skip_start
from .peak import peak_to_peak, peak_to_peak_series, window_samples
from .rms import jitter_rms, stability_rms
from .spectral import (
    average_weight,
    jitter_rms_from_frf,
    jitter_rms_from_psd,
    jitter_weight,
    one_sided_psd,
    response_psd,
    rms_from_psd,
    stability_rms_from_psd,
    stability_weight,
)

__all__ = [
    "INTERPRETATIONS",
    "BudgetLine",
    "Contribution",
    "RecordTooShortError",
    "RequirementCheck",
    "WindowError",
    "ape",
    "average_weight",
    "budget",
    "check_requirement",
    "jitter_rms",
    "jitter_rms_from_frf",
    "jitter_rms_from_psd",
    "jitter_weight",
    "margin",
    "rss",
    "metric_values",
    "mpe",
    "one_sided_psd",
    "pde",
    "peak_to_peak",
    "peak_to_peak_series",
    "response_psd",
    "rms",
    "rms_from_psd",
    "rpe",
    "skip_start",
    "sliding_means",
    "stability_rms",
    "stability_rms_from_psd",
    "stability_weight",
    "window_samples",
]
