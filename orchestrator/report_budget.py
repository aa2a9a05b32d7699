"""The budget chart of a campaign report: RSS bars against requirements, event heat maps.

:func:`budget_grid` arranges a summary's rows as arrays (events x instrument-axis per
configuration group); ``_budget_figure`` draws them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import matplotlib
import matplotlib.colorbar
import numpy as np
from matplotlib.figure import Figure

from .campaign import RSS_EVENT
from .report_verdict import metric_words

__all__ = ["BudgetGrid", "budget_grid"]

_MAX_GROUPS = 8  # configuration x sweep groups drawn in one figure


def _groups(rows):
    seen = []
    for r in rows:
        g = (r["configuration"], r["sweep"])
        if g not in seen:
            seen.append(g)
    return seen


def _group_label(g) -> str:
    return " | ".join(x for x in g if x)


# ----------------------------------------------------------------------------- figures



@dataclass(frozen=True)
class BudgetGrid:
    """The budget as arrays: events x (instrument, axis) per configuration group.

    Parameters
    ----------
    groups : tuple of tuple
        ``(configuration, sweep)`` of each group, first = the baseline (e.g. isolation
        off).
    columns : tuple of (str, str)
        ``(instrument, axis)`` of each column, in campaign order.
    events : tuple of str
        Event names, then ``RSS``.
    values : ndarray, shape (n_groups, n_events + 1, n_columns)
        Metric values (report unit); NaN where a case failed or is missing.
    requirement : ndarray, shape (n_columns,)
        Requirement of each column (NaN where none).
    """

    groups: tuple
    columns: tuple
    events: tuple
    values: np.ndarray
    requirement: np.ndarray

    def change_pct(self, gi: int) -> np.ndarray:
        """Change of group ``gi`` against the baseline, 100 (g - base) / base (%)."""
        base = self.values[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(base > 0, 100.0 * (self.values[gi] - base) / base, np.nan)


def budget_grid(rows, instruments) -> BudgetGrid:
    """Arrange summary rows of one metric and window as a :class:`BudgetGrid`.

    Parameters
    ----------
    rows : list of dict
        Summary rows (one metric and window), events and ``RSS``.
    instruments : dict
        Instrument -> {axis: variable}, in campaign order.
    """
    groups = tuple(_groups(rows)[:_MAX_GROUPS])
    # campaign order: the summary keeps it, campaign.json sorts its keys
    columns = tuple(dict.fromkeys((r["instrument"], r["axis"]) for r in rows
                                  if r["instrument"] in instruments))
    events = tuple(e for e in dict.fromkeys(r["event"] for r in rows) if e != RSS_EVENT)
    events += (RSS_EVENT,)
    gi = {g: i for i, g in enumerate(groups)}
    ei = {e: i for i, e in enumerate(events)}
    ci = {c: i for i, c in enumerate(columns)}
    values = np.full((len(groups), len(events), len(columns)), np.nan)
    requirement = np.full(len(columns), np.nan)
    for r in rows:
        g, c = (r["configuration"], r["sweep"]), (r["instrument"], r["axis"])
        if g not in gi or c not in ci or r["event"] not in ei:
            continue
        v = r["value"]
        values[gi[g], ei[r["event"]], ci[c]] = np.nan if v is None else v
        req = r.get("requirement")
        if r["event"] == RSS_EVENT and req is not None and not math.isnan(req):
            requirement[ci[c]] = req
    return BudgetGrid(groups, columns, events, values, requirement)


_GROUP_COLORS = ("#8c8c8c", "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                 "#8c564b", "#e377c2")


def _column_axis_labels(ax, columns):
    """Axis names as tick labels, instrument names centred under their axes."""
    ax.set_xticks(np.arange(len(columns)), [a for _, a in columns], fontsize=9)
    start = 0
    for k in range(1, len(columns) + 1):
        if k == len(columns) or columns[k][0] != columns[start][0]:
            ax.annotate(columns[start][0], xy=((start + k - 1) / 2, 0), xycoords=("data", "axes fraction"),
                        xytext=(0, -22), textcoords="offset points", ha="center", va="top",
                        fontsize=9, fontweight="bold")
            if k < len(columns):
                ax.axvline(k - 0.5, color="#444", lw=0.8)
            start = k


def _heatmap(ax, grid, data, cmap, norm, fmt, title):
    masked = np.ma.masked_invalid(data)
    cm = matplotlib.colormaps[cmap].with_extremes(bad="#e8e8e8")
    im = ax.imshow(masked, cmap=cm, norm=norm, aspect="auto", interpolation="nearest")
    ax.set_yticks(np.arange(len(grid.events)), grid.events, fontsize=9)
    ax.get_yticklabels()[-1].set_fontweight("bold")
    ax.axhline(len(grid.events) - 1.5, color="k", lw=1.2)  # events above, RSS below
    for (i, j), v in np.ndenumerate(data):
        text = "–" if not np.isfinite(v) else fmt(v)
        rgba = im.cmap(im.norm(v)) if np.isfinite(v) else (1, 1, 1, 1)
        dark = 0.299 * rgba[0] + 0.587 * rgba[1] + 0.114 * rgba[2] < 0.5
        ax.text(j, i, text, ha="center", va="center", fontsize=8,
                color="white" if dark else "black")
    _column_axis_labels(ax, grid.columns)
    ax.set_title(title, fontsize=10, loc="left")
    return im


def _sig(v):
    return f"{v:.2g}" if abs(v) < 10 else f"{v:.0f}"


def _plain_log_labels(axis, lo, hi, minor_decades=2.0):
    """Tick labels 0.1, 2, 50 instead of 10^-1, 2x10^0, 5x10^1 on a log axis.

    Minor ticks are labelled only when the axis spans fewer than ``minor_decades``.
    """
    # deferred: plotting only
    from matplotlib.ticker import FuncFormatter, NullFormatter

    def minor(v, _):
        mantissa = round(v / 10 ** np.floor(np.log10(v)), 6) if v > 0 else 0
        return f"{v:g}" if mantissa in (2.0, 5.0) else ""   # 1-2-5: labels never touch

    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    few_decades = np.log10(hi / lo) < minor_decades if lo > 0 else False
    axis.set_minor_formatter(FuncFormatter(minor) if few_decades else NullFormatter())


def _budget_figure(rows, instruments, unit, metric, window):
    """Budget chart: RSS per instrument and axis per group, and event x axis heat maps.

    Top: the RSS total of every instrument and axis, one bar per configuration (the first
    one, e.g. isolation off, grey) side by side on a log axis, the requirement as a black
    bar across each pair and the change against the first configuration written above.
    Below: a heat map of every event's value in the first configuration (log colour
    scale, values written in the cells), and one heat map per further configuration of
    its change against the first (%, blue = less jitter, red = more; cells written).
    """
    # deferred: plotting only
    from matplotlib.colors import LogNorm, Normalize

    grid = budget_grid(rows, instruments)
    ng, ne, nc = grid.values.shape
    n_change = ng - 1   # every further configuration (budget_grid keeps _MAX_GROUPS)
    width = max(10.0, 0.62 * nc + 3.5)
    hmap_h = 0.26 * ne + 1.3
    heights = [3.6] + [hmap_h] * (1 + n_change)
    fig = Figure(figsize=(width, sum(heights) + 0.9))
    axs = fig.subplots(len(heights), 1, squeeze=False,
                       gridspec_kw={"height_ratios": heights})[:, 0]
    labels = [_group_label(g) or "all cases" for g in grid.groups]

    # RSS totals, grouped bars on a log axis
    ax = axs[0]
    ax.set_label("rss")
    rss = grid.values[:, -1, :]
    x = np.arange(nc)
    w = 0.8 / ng
    for gi in range(ng):
        h = np.where(np.isfinite(rss[gi]) & (rss[gi] > 0), rss[gi], np.nan)
        ax.bar(x + (gi - (ng - 1) / 2) * w, h, w, color=_GROUP_COLORS[gi % len(_GROUP_COLORS)],
               label=labels[gi], edgecolor="white", linewidth=0.5)
    have_req = np.isfinite(grid.requirement)
    if have_req.any():
        ax.hlines(grid.requirement[have_req], x[have_req] - 0.45, x[have_req] + 0.45,
                  colors="k", lw=2.2, label="requirement")
    if ng > 1:
        change = 100.0 * (rss[-1] - rss[0]) / rss[0]
        top = np.nanmax(np.vstack([rss, grid.requirement[None, :]]), axis=0)
        for j in range(nc):
            if np.isfinite(change[j]):
                ax.annotate(f"{change[j]:+.0f} %" if abs(change[j]) >= 0.5 else "0 %",
                            (x[j], top[j]), xytext=(0, 3), textcoords="offset points",
                            ha="center", va="bottom", fontsize=8,
                            color="#1f4e9c" if change[j] <= -0.5 else "#444")
    shown = np.concatenate([rss.ravel(), grid.requirement])
    shown = shown[np.isfinite(shown) & (shown > 0)]
    if shown.size:
        ax.set_yscale("log")
        ax.set_ylim(10 ** np.floor(np.log10(shown.min() / 2)), shown.max() * 4)
        _plain_log_labels(ax.yaxis, *ax.get_ylim())
    ax.set_xlim(-0.5, nc - 0.5)
    ax.set_ylabel(f"RSS ({unit})")
    ax.grid(axis="y", which="both", alpha=0.25)
    _column_axis_labels(ax, grid.columns)
    # above the bars, as many entries a row as fit the width (never cut at an edge)
    entry = max(0.061 * len(t) + 0.6 for t in labels + ["requirement"])   # in, at 8 pt
    change_note = f"; % = {labels[-1]} vs {labels[0]}" if ng > 1 else ""
    ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), fontsize=8, frameon=False,
              ncol=max(1, min(ng + 1, int(0.8 * width / entry))), alignment="left",
              title=f"RSS total{change_note}", title_fontsize=10)
    # the same right margin as the heat maps' colour bars, so the columns line up
    spare, _ = matplotlib.colorbar.make_axes_gridspec(ax, fraction=0.03, pad=0.01)
    spare.set_axis_off()

    # every event in the baseline group
    base = grid.values[0]
    finite = base[np.isfinite(base) & (base > 0)]
    norm = (LogNorm(vmin=finite.min(), vmax=finite.max()) if finite.size
            and finite.min() < finite.max() else Normalize())
    axs[1].set_label("events")
    im = _heatmap(axs[1], grid, np.where(base > 0, base, np.nan), "viridis", norm, _sig,
                  f"{metric_words(metric)} ({unit}), {labels[0]}")
    cbar = fig.colorbar(im, ax=axs[1], pad=0.01, fraction=0.03)
    cbar.set_label(unit, fontsize=8)
    if isinstance(norm, LogNorm):
        _plain_log_labels(cbar.ax.yaxis, norm.vmin, norm.vmax)

    # change of each further group against the baseline
    for k in range(n_change):
        gi = k + 1
        a = axs[2 + k]
        a.set_label(f"change:{labels[gi]}")
        chg = grid.change_pct(gi)
        im = _heatmap(a, grid, chg, "RdBu_r", Normalize(-100.0, 100.0),
                      lambda v: f"{v:+.0f}" if abs(v) >= 0.5 else "0",
                      f"change with {labels[gi]} vs {labels[0]} (%; blue: less jitter)")
        fig.colorbar(im, ax=a, pad=0.01, fraction=0.03).set_label("%", fontsize=8)

    fig.suptitle(f"Jitter budget: {metric_words(metric, window)}, {unit}", fontsize=12,
                 x=0.01, ha="left")
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.15 / fig.get_figheight()))   # room for the title
    return fig


