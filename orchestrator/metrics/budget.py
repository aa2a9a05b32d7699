"""Jitter budgets: RSS across disturbance events, margins and dominant events.

Each disturbance event is simulated alone; its jitter at every instrument and axis is one
budget entry.  Events are taken as independent, so the total at an instrument and axis is
the root-sum-square over events, ``total = sqrt(sum_e v_e^2)``, and an event's share of the
total is ``v_e^2 / total^2`` (the shares add up to 1).

Margin
------
``margin = requirement − total`` (unit of the values; positive means met) and
``margin_ratio = margin / requirement`` (dimensionless; ``100 * margin_ratio`` is the margin
in percent of the requirement).  The line passes when ``total <= requirement``.  Without a
requirement, margin and ratio are NaN and ``passed`` is None.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

__all__ = ["BudgetLine", "Contribution", "budget", "margin", "rss"]


def rss(values, axis=None):
    """Root-sum-square of independent contributions.

    Parameters
    ----------
    values : array_like, shape (n, ...)
        Contributions (any unit).
    axis : int, optional
        Axis summed over; all elements if omitted.

    Returns
    -------
    total : float or ndarray
        ``sqrt(sum(values**2, axis))`` (unit of ``values``).
    """
    v = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(v)):
        raise ValueError("values for the RSS contain non-finite numbers; expected finite values")
    out = np.sqrt(np.sum(v * v, axis=axis))
    return out[()] if np.ndim(out) == 0 else out


def margin(value, requirement):
    """Margin of a value against a requirement.

    Parameters
    ----------
    value : float or array_like
        Achieved value (unit).
    requirement : float or array_like
        Allowed value (unit), positive.

    Returns
    -------
    absolute : float or ndarray
        ``requirement − value`` (unit); positive when met.
    ratio : float or ndarray
        ``(requirement − value) / requirement`` (dimensionless).
    """
    v = np.asarray(value, dtype=float)
    r = np.asarray(requirement, dtype=float)
    if np.any(r <= 0):
        raise ValueError(f"requirement is {requirement!r}; expected a positive value")
    a = r - v
    out = (a, a / r)
    return tuple(o[()] if o.ndim == 0 else o for o in out)


@dataclass(frozen=True)
class Contribution:
    """One event's part in a budget line.

    Attributes
    ----------
    event : str
        Disturbance event name.
    value : float
        Its jitter (unit of the budget).
    share : float
        ``value**2 / total**2`` (fraction of the squared total).
    """

    event: str
    value: float
    share: float


@dataclass(frozen=True)
class BudgetLine:
    """RSS total of one instrument axis against its requirement.

    Attributes
    ----------
    instrument, axis : str
        Where the jitter is measured.
    total : float
        RSS over events (unit).
    requirement : float
        Allowed value (unit), NaN if none.
    margin : float
        ``requirement − total`` (unit).
    margin_ratio : float
        ``margin / requirement`` (dimensionless).
    passed : bool or None
        ``total <= requirement``; None without a requirement.
    contributions : tuple of Contribution
        Events sorted by decreasing share.
    """

    instrument: str
    axis: str
    total: float
    requirement: float
    margin: float
    margin_ratio: float
    passed: bool | None
    contributions: tuple[Contribution, ...]

    @property
    def margin_percent(self) -> float:
        """Margin in percent of the requirement."""
        return 100.0 * self.margin_ratio

    @property
    def dominant(self) -> str:
        """Name of the event with the largest share."""
        return self.contributions[0].event


def _entry(e):
    if isinstance(e, Mapping):
        return str(e["event"]), str(e["instrument"]), str(e["axis"]), float(e["value"])
    event, instrument, axis, value = e
    return str(event), str(instrument), str(axis), float(value)


def budget(entries: Iterable, requirements: Mapping | None = None) -> list[BudgetLine]:
    """RSS budget per instrument and axis, with margins and sorted contributions.

    Parameters
    ----------
    entries : iterable of (event, instrument, axis, value) or mappings with those keys
        One jitter value per event, instrument and axis (unit of your choice, e.g. arcsec).
    requirements : mapping, optional
        Allowed values, keyed by ``(instrument, axis)`` or by ``instrument`` (all axes);
        the ``(instrument, axis)`` key wins.

    Returns
    -------
    lines : list of BudgetLine
        One per (instrument, axis) in order of first appearance.

    Raises
    ------
    ValueError
        If an (event, instrument, axis) appears twice or a value is negative or not finite.
    """
    requirements = requirements or {}
    groups: dict[tuple[str, str], dict[str, float]] = {}
    for raw in entries:
        event, instrument, axis, value = _entry(raw)
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(
                f"jitter of event {event!r} at {instrument}/{axis} is {value!r}; "
                "expected a finite non-negative value"
            )
        g = groups.setdefault((instrument, axis), {})
        if event in g:
            raise ValueError(f"event {event!r} appears twice for {instrument}/{axis}")
        g[event] = value
    lines = []
    for (instrument, axis), g in groups.items():
        total = float(rss(list(g.values())))
        sq = total * total
        contributions = tuple(
            sorted(
                (Contribution(e, v, v * v / sq if sq > 0 else 0.0) for e, v in g.items()),
                key=lambda c: (-c.share, c.event),
            )
        )
        req = requirements.get((instrument, axis), requirements.get(instrument))
        if req is None:
            line = BudgetLine(instrument, axis, total, math.nan, math.nan, math.nan, None,
                              contributions)
        else:
            a, r = margin(total, req)
            line = BudgetLine(instrument, axis, total, float(req), float(a), float(r),
                              bool(total <= req), contributions)
        lines.append(line)
    return lines
