"""Uncertainty: distributions of the inputs, samples, and the statistics of a budget.

Pure numerics, no FMU: :func:`draw` samples the uncertain parameters of an
``[uncertainty]`` table, and :func:`statistics` turns the samples of a budget (one
value per sample: the RSS over the events) into what ECSS-E-ST-60-10C asks of a
statistical requirement ``prob(X < X_max) >= P_c``: the value at each confidence level
with a bootstrap interval that says whether the sample count suffices, the probability
of meeting the requirement, and two sensitivity rankings of every uncertain input: the
share of the budget's (rank) variance it explains alone (:func:`first_order_index`, which
sees a resonance crossed in the middle of a frequency range) and its Spearman rank
correlation with the budget (the sign: more of the input, more or less budget).

Interpretation (stated in every result): each sample's value is the worst window of its
own record (windowed metrics are maxima over time), so a sample meets the requirement only
if it does at all times, and the probability runs over the samples: ECSS's *ensemble*
interpretation, as :func:`orchestrator.metrics.check_requirement` computes it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..metrics import check_requirement

__all__ = ["Distribution", "Uncertain", "draw", "statistics", "rank_correlation",
           "first_order_index", "quantile_upper_bound", "proportion_lower_bound",
           "samples_for_bound", "INTERPRETATION", "ASSURANCE", "UncertaintyError"]

INTERPRETATION = ("ensemble: each sample is the worst window of its record (it meets the "
                  "requirement only if it does at all times), the probability is over the "
                  "samples")

#: What ``upper_bound`` and ``p_meet_low`` of :func:`statistics` state.
ASSURANCE = ("upper_bound: an order statistic of the samples that lies above the true "
             "P_c value with probability >= assurance, whatever the distribution of the "
             "budget (binomial, exact for a continuous budget, conservative otherwise); "
             "meets_assured: that bound is below the requirement, equivalently the "
             "one-sided Clopper-Pearson bound p_meet_low of prob(X < X_max) is >= P_c")

DISTRIBUTIONS = ("uniform", "normal", "lognormal")
_BIG = np.finfo(float).max / 4   # the stand-in of an infinite sample
KINDS = ("modal_frequency", "modal_damping", "amplitude", "phase", "frequency", "gain")
# the kinds that perturb the reduced structure's modes, and those that change a loop (the
# others drive it)
MODAL_KINDS = ("modal_frequency", "modal_damping")
LOOP_KINDS = MODAL_KINDS + ("gain",)


class UncertaintyError(ValueError):
    """An ``[uncertainty]`` table that cannot be sampled."""


@dataclass(frozen=True)
class Distribution:
    """A scalar distribution, optionally truncated to ``[low, high]``.

    ``uniform``: on ``[low, high]``.  ``normal``: ``mean``, ``std``.  ``lognormal``:
    ``median`` and ``sigma`` of the logarithm.  Truncation redraws the samples outside.
    """

    kind: str
    low: float = -math.inf
    high: float = math.inf
    mean: float = 0.0
    std: float = 0.0
    median: float = 1.0
    sigma: float = 0.0

    def __post_init__(self):
        if self.kind not in DISTRIBUTIONS:
            raise UncertaintyError(f"distribution {self.kind!r} is unknown; expected one of "
                                   f"{list(DISTRIBUTIONS)}")
        if not self.low < self.high:
            raise UncertaintyError(f"{self.kind} distribution has low = {self.low} >= "
                                   f"high = {self.high}; expected low < high")
        if self.kind == "uniform" and not (math.isfinite(self.low)
                                           and math.isfinite(self.high)):
            raise UncertaintyError("a uniform distribution needs finite low and high")
        if self.kind == "normal" and not self.std > 0:
            raise UncertaintyError(f"a normal distribution needs std > 0, got {self.std}")
        if self.kind == "lognormal" and not (self.sigma > 0 and self.median > 0):
            raise UncertaintyError("a lognormal distribution needs median > 0 and sigma > 0")

    def sample(self, rng: np.random.Generator, size) -> np.ndarray:
        """Samples inside the bounds.

        Parameters
        ----------
        rng : numpy.random.Generator
        size : int or tuple of int
            Shape of the result.

        Returns
        -------
        ndarray, shape ``size``
        """
        size = tuple(np.atleast_1d(size))
        n = int(np.prod(size))
        out = np.empty(0)
        for _ in range(1000):
            if self.kind == "uniform":
                x = rng.uniform(self.low, self.high, n)
            elif self.kind == "normal":
                x = rng.normal(self.mean, self.std, n)
            else:
                x = self.median * np.exp(rng.normal(0.0, self.sigma, n))
            out = np.concatenate([out, x[(x >= self.low) & (x <= self.high)]])
            if out.size >= n:
                return out[:n].reshape(size)
        raise UncertaintyError(f"the {self.kind} distribution has almost no mass in "
                               f"[{self.low}, {self.high}]; widen the bounds")


@dataclass(frozen=True)
class Uncertain:
    """One uncertain input of a budget.

    Attributes
    ----------
    name : str
    kind : str
        ``modal_frequency`` (factor on the modal frequencies), ``modal_damping`` (factor
        on the modal damping ratios), ``amplitude`` (factor on a source's wrench),
        ``phase`` (random phases of a source: its ``seed``), ``frequency`` (factor on a
        source's line and repetition frequencies: its ``frequency_scale``,
        :func:`distfmu.presets.retimed`), ``gain`` (factor on a controller's gain).
    distribution : Distribution or None
        None for ``phase``.
    instances : tuple of str
        Sources (``amplitude``, ``phase``, ``frequency``) or controllers (``gain``);
        empty for the modal kinds.
    per_mode : bool
        Modal kinds: an independent draw per mode (else one factor for all).
    band : tuple of float
        Modal kinds: modes with frequencies in ``[low, high]`` Hz.
    """

    name: str
    kind: str
    distribution: Distribution | None
    instances: tuple = ()
    per_mode: bool = False
    band: tuple = (0.0, math.inf)


@dataclass(frozen=True)
class Draws:
    """The samples of every uncertain input: ``values[name]`` shape (n, k)."""

    n: int
    values: dict = field(default_factory=dict)
    modes: dict = field(default_factory=dict)   # name -> indices of the modes it moves
    labels: dict = field(default_factory=dict)  # name -> the instances of its columns

    def scalar_inputs(self) -> dict:
        """Every scalar input (a mode of a per-mode draw is one) -> its samples (n,)."""
        out = {}
        for name, v in self.values.items():
            modes = self.modes.get(name)
            labels = self.labels.get(name)
            if v.shape[1] == 1:
                out[name] = v[:, 0]
                continue
            for j in range(v.shape[1]):
                tag = (f"mode {modes[j] + 1}" if modes is not None else
                       labels[j] if labels else f"{j + 1}")
                out[f"{name} [{tag}]"] = v[:, j]
        return out


def draw(items, n: int, seed: int, frequencies_hz=None) -> Draws:
    """Sample every uncertain input ``n`` times.

    Sample ``s`` is drawn from its own generator, ``numpy.random.default_rng([seed,
    s])``: the first ``n`` samples of a larger count are these ``n``, so a Monte Carlo
    run can be extended, or resumed from the samples it kept, without changing them.

    Parameters
    ----------
    items : sequence of Uncertain
    n : int
        Samples (>= 1).
    seed : int
        Seed (>= 0); the same seed gives the same samples.
    frequencies_hz : ndarray, shape (n_m,), optional
        Modal frequencies of the structure (the modal kinds select modes by band).

    Returns
    -------
    Draws
    """
    if not (isinstance(n, int) and n >= 1):
        raise UncertaintyError(f"samples is {n!r}; expected a whole number >= 1")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise UncertaintyError(f"seed is {seed!r}; expected a whole number >= 0")
    values, modes = {}, {}
    for it in items:
        if it.kind in MODAL_KINDS:
            f = np.asarray(frequencies_hz if frequencies_hz is not None else [], float)
            idx = np.flatnonzero((f >= it.band[0]) & (f <= it.band[1]) & (f > 0))
            if idx.size == 0:
                raise UncertaintyError(f"uncertain {it.name!r}: no mode in the band "
                                       f"{list(it.band)} Hz")
            modes[it.name] = idx
            k = idx.size if it.per_mode else 1
        else:   # amplitude, phase, frequency, gain: one independent value per instance
            k = len(it.instances)
        values[it.name] = np.empty((n, k), np.int64 if it.kind == "phase" else float)
    for s in range(n):
        rng = np.random.default_rng([int(seed), s])
        for it in items:
            row = values[it.name][s]
            if it.kind == "phase":
                row[:] = rng.integers(1, 2**31 - 1, size=row.size)
            else:
                row[:] = it.distribution.sample(rng, row.size)
    labels = {it.name: list(it.instances) for it in items if it.instances}
    return Draws(n, values, modes, labels)


def _ranks(v: np.ndarray) -> np.ndarray:
    """Ranks 0 .. n-1 of a sample, ties given their mean rank."""
    order = np.argsort(v, kind="mergesort")
    r = np.empty(v.size)
    r[order] = np.arange(v.size, dtype=float)
    _, inv, counts = np.unique(v, return_inverse=True, return_counts=True)
    sums = np.bincount(inv, weights=r)
    return (sums / counts)[inv]


def rank_correlation(x: np.ndarray, y: np.ndarray) -> float:
    """Spearman's rank correlation of two samples (ties get their mean rank).

    Parameters
    ----------
    x, y : ndarray, shape (n,)

    Returns
    -------
    float
        In [-1, 1]; 0 when either sample is constant.
    """
    return _rank_corr(_ranks(np.asarray(x, float)), _ranks(np.asarray(y, float)))


def _rank_corr(rx: np.ndarray, ry: np.ndarray) -> float:
    """Pearson correlation of two rank samples."""
    sx, sy = rx.std(), ry.std()
    if sx == 0 or sy == 0:
        return 0.0
    return float(np.mean((rx - rx.mean()) * (ry - ry.mean())) / (sx * sy))


def first_order_index(x: np.ndarray, y: np.ndarray, bins: int | None = None) -> float:
    """The share of the variance of ``y``'s ranks that ``x`` alone explains, whatever the
    shape of the dependence: the correlation ratio ``Var(E[r(y) | x]) / Var(r(y))``
    (a first-order sensitivity index), with ``E[. | x]`` the mean over equal-count bins
    of ``x``, less its bias under independence (``(bins - 1) / (n - 1)``, as an adjusted
    R^2).

    A rank correlation sees only the monotone part of a dependence: a lightly damped
    mode whose frequency range straddles a disturbance line gives a resonance peak in
    the middle of the range, a rank correlation near 0 and an index near 1.

    Parameters
    ----------
    x, y : ndarray, shape (n,)
        The input and the budget (ranks are taken, so an infinite value is the largest).
    bins : int, optional
        Bins of ``x`` (default ``n // 40``, between 2 and 25: at least 40 samples a bin).

    Returns
    -------
    float
        About 0 (its sampling scatter, either sign) for an input that does not matter, 1
        for a ``y`` that is a function of ``x`` alone; 0 when either sample is constant.
    """
    return _first_order(_ranks(np.asarray(x, float)), _ranks(np.asarray(y, float)), bins)


def _first_order(rx: np.ndarray, ry: np.ndarray, bins: int | None = None) -> float:
    """:func:`first_order_index` of rank samples."""
    n = rx.size
    if n < 3 or np.ptp(rx) == 0:
        return 0.0
    sy = np.sum((ry - ry.mean()) ** 2)
    if sy == 0:
        return 0.0
    b = int(bins) if bins is not None else max(2, min(25, n // 40))
    b = max(2, min(b, n - 1))
    label = np.minimum((rx * b / n).astype(int), b - 1)
    count = np.bincount(label, minlength=b)
    mean = np.bincount(label, weights=ry, minlength=b) / np.maximum(count, 1)
    eta2 = float(np.sum(count * (mean - ry.mean()) ** 2) / sy)
    bias = (b - 1) / (n - 1)
    return (eta2 - bias) / (1.0 - bias)


def samples_for_bound(p: float, assurance: float) -> int:
    """The fewest samples whose largest lies above the ``p``-quantile with probability
    ``>= assurance``: the smallest ``n`` with ``1 - p^n >= assurance`` (59 for 95 % at
    95 %, Wilks' count).

    Parameters
    ----------
    p : float
        The level of the quantile, in (0, 1).
    assurance : float
        The probability that the bound lies above the quantile, in (0, 1).

    Returns
    -------
    int
    """
    _check_levels(p, assurance)
    n = max(1, math.ceil(math.log1p(-assurance) / math.log(p)))
    while n > 1 and -math.expm1((n - 1) * math.log(p)) >= assurance:   # rounding
        n -= 1
    while -math.expm1(n * math.log(p)) < assurance:
        n += 1
    return n


def _check_levels(p: float | None, assurance: float) -> None:
    if not ((p is None or 0 < p < 1) and 0 < assurance < 1):
        raise UncertaintyError(f"a confidence bound needs a level and an assurance in "
                               f"(0, 1); got {p!r} and {assurance!r}")


def quantile_upper_bound(samples, p: float, assurance: float = 0.95) -> tuple:
    """Distribution-free upper confidence bound of the ``p``-quantile of the samples.

    The ``k``-th smallest of ``n`` independent samples lies above the true
    ``p``-quantile ``q_p`` when fewer than ``k`` samples fall below ``q_p``, which has
    the probability ``P(Binomial(n, p) <= k - 1)`` whatever the distribution (for a
    continuous one; at least that otherwise).  The bound is the order statistic of the
    smallest ``k`` that makes this ``>= assurance``: what a "95/95" statement of a
    Monte Carlo budget quotes.

    Parameters
    ----------
    samples : array_like, shape (n,)
        Independent samples; ``inf`` stands for a sample outside the model (above every
        bound).
    p : float
        The level of the quantile (the requirement's ``P_c``), in (0, 1).
    assurance : float
        The probability that the bound lies above ``q_p``, in (0, 1).

    Returns
    -------
    (bound, k, need)
        The bound (``inf`` when the samples are too few for one, or when the ``k``-th
        sample is outside the model), its rank ``k`` (1-based; None when there is no
        bound) and :func:`samples_for_bound`, the fewest samples that give one.
    """
    from scipy.special import bdtr

    _check_levels(p, assurance)
    x = np.sort(np.asarray(samples, float))
    n, need = x.size, samples_for_bound(p, assurance)
    if n < need:
        return math.inf, None, need
    cdf = bdtr(np.arange(n), n, p)              # P(Binomial(n, p) <= j), j = 0 .. n - 1
    j = min(int(np.searchsorted(cdf, assurance)), n - 1)
    return float(x[j]), j + 1, need


def proportion_lower_bound(successes: int, n: int, assurance: float = 0.95) -> float:
    """One-sided Clopper-Pearson lower confidence bound of a probability from
    ``successes`` of ``n`` independent trials: the ``p`` at which ``P(Binomial(n, p) >=
    successes) = 1 - assurance`` (0 without a success).

    Parameters
    ----------
    successes, n : int
        Counts, ``0 <= successes <= n``, ``n >= 1``.
    assurance : float
        The probability that the bound lies below the true probability, in (0, 1).

    Returns
    -------
    float
    """
    from scipy.special import betaincinv

    _check_levels(None, assurance)
    if not 0 <= successes <= n or n < 1:
        raise UncertaintyError(f"{successes} successes of {n} trials is not a count")
    if successes == 0:
        return 0.0
    return float(betaincinv(successes, n - successes + 1, 1.0 - assurance))


def statistics(samples: np.ndarray, confidence, requirement: float = math.nan, *,
               inputs: dict | None = None, n_boot: int = 400, seed: int = 0,
               assurance: float = 0.95) -> dict:
    """ECSS statistics of the samples of one budget value.

    Parameters
    ----------
    samples : ndarray, shape (n,)
        The budget value of every sample (e.g. arcsec); ``inf`` for a sample outside
        the model (an unstable loop, a rail reached), which exceeds every requirement.
    confidence : sequence of float
        Levels ``P_c`` in (0, 1), e.g. ``0.95, 0.9973``.
    requirement : float
        ``X_max`` (NaN for none).
    inputs : dict of str to ndarray (n,), optional
        The uncertain scalar inputs, for the sensitivity ranking.
    n_boot : int
        Bootstrap resamples of the quantile interval.
    seed : int
        Seed of the bootstrap.
    assurance : float
        The probability with which ``upper_bound`` lies above the true value at each
        level (:func:`quantile_upper_bound`), in (0, 1).

    Returns
    -------
    dict
        ``mean``, ``std`` (of the finite samples; ``n_infinite`` counts the others: a
        sample outside the model, which fails every bound), ``quantiles`` (``P_c -> {value, low, high, rel_width,
        converged}``, the 95 % bootstrap interval and ``converged`` when its width is
        below 2 % of the value, ``samples_for_2pct`` the sample count at which it would be
        (the interval narrowing as ``1/sqrt(n)``; None when the value is infinite),
        ``upper_bound`` with its rank ``upper_rank`` and ``samples_for_bound``
        (:func:`quantile_upper_bound`: above the true value with probability
        ``>= assurance``, whatever the distribution), ``meets``: ``prob(X < X_max) >=
        P_c`` on the samples and the value at ``P_c`` below ``X_max`` (an infinite value
        never meets), and ``meets_assured``: ``upper_bound < X_max``), ``p_meet``
        (fraction of samples ``< X_max``, an infinite one never below it, with its
        binomial standard error ``p_meet_se`` and its Clopper-Pearson lower bound
        ``p_meet_low`` at ``assurance``),
        ``assurance``, ``sensitivity`` (input -> rank
        correlation, largest magnitude first), ``first_order`` (input ->
        :func:`first_order_index`, largest first: what drives the budget whether or not
        monotonically) and ``interpretation``.
    """
    x = np.asarray(samples, float)
    # a sample outside the model is inf; the order statistics need a finite stand-in
    x = np.where(np.isfinite(x), x, _BIG)
    rng = np.random.default_rng(seed)
    boot = rng.integers(0, x.size, size=(n_boot, x.size))
    fin = x[x < _BIG]
    out = {"n": int(x.size), "n_infinite": int(x.size - fin.size),
           "mean": float(fin.mean()) if fin.size else math.inf,
           "std": float(fin.std(ddof=1)) if fin.size > 1 else 0.0, "quantiles": {},
           "interpretation": INTERPRETATION, "assurance": float(assurance)}
    top = float(fin.max()) if fin.size else -math.inf

    def cap(q):   # interpolated towards an infinite sample: infinite
        return math.inf if q > top else float(q)

    for pc in confidence:
        v = cap(np.quantile(x, pc))
        bq = np.quantile(x[boot], pc, axis=1)
        lo, hi = (cap(q) for q in np.quantile(bq, [0.025, 0.975]))
        # every resample gives the same value (a zero line, a value every sample shares):
        # the interval has no width; otherwise relative, infinite at 0 or above the model
        width = (0.0 if hi == lo else (hi - lo) / abs(v) if v and math.isfinite(hi)
                 else math.inf)
        # the interval narrows as 1/sqrt(n): the samples it would take to reach 2 %
        need = (x.size if width < 0.02 else math.ceil(x.size * (width / 0.02) ** 2)
                if 0 < width < math.inf else None)
        ub, rank, least = quantile_upper_bound(x, pc, assurance)
        out["quantiles"][float(pc)] = {"value": v, "low": lo, "high": hi,
                                       "rel_width": width, "converged": bool(width < 0.02),
                                       "samples_for_2pct": need,
                                       "upper_bound": cap(ub), "upper_rank": rank,
                                       "samples_for_bound": least}
    if not math.isnan(requirement):
        for pc in confidence:
            chk = check_requirement(x[:, None], requirement, pc, "ensemble")
            q = out["quantiles"][float(pc)]
            # the interpolated value can lie above X_max (or be infinite) while the
            # fraction below X_max reaches P_c: both must hold, or the line reads false
            q["meets"] = bool(chk.passed and q["value"] < requirement)
            q["meets_assured"] = bool(q["upper_bound"] < requirement)
        p = check_requirement(x[:, None], requirement, 1.0, "ensemble").probability
        out["p_meet"] = p
        out["p_meet_se"] = math.sqrt(max(p * (1 - p), 0.0) / x.size)
        out["p_meet_low"] = proportion_lower_bound(int(np.sum(x < requirement)), x.size,
                                                   assurance)
    ry = _ranks(x)   # each sample's ranks once for both measures
    ranked = {name: _ranks(np.asarray(v, float)) for name, v in (inputs or {}).items()}
    sens = {name: _rank_corr(rv, ry) for name, rv in ranked.items()}
    out["sensitivity"] = dict(sorted(sens.items(), key=lambda kv: -abs(kv[1])))
    first = {name: _first_order(rv, ry) for name, rv in ranked.items()}
    out["first_order"] = dict(sorted(first.items(), key=lambda kv: -kv[1]))
    return out
