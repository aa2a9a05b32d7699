"""Time-domain figures of a campaign report: line-of-sight histories, boresight scatter, FRFs.

The histories follow what dominates each axis: one figure per dominant event, a panel
per axis it dominates (of several instruments whose axis it dominates, the one nearest
failing: the others move alike and are named in the caption, not drawn again), every
configuration overlaid in its own colour and line style (equal traces stay visible), the
worst window of the budget metric shaded and the requirement drawn over it (a
peak-to-peak requirement is a band of its height centred on the worst window's
mid-range: the trace leaves the band where the window fails).  The boresight is drawn
over each configuration's worst window, inside the requirement's box centred there.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from . import metrics as M

__all__ = [
    "Marking",
    "Panel",
    "STYLES",
    "ReportError",
    "frf_figure",
    "history_figure",
    "legend_above",
    "scatter_axes",
    "joint_worst_window",
    "scatter_figure",
    "style",
    "worst_window",
]


class ReportError(ValueError):
    """A campaign folder that cannot be reported on."""


_ORDER = {"roll": 0, "pitch": 1, "yaw": 2}
_REQ = "crimson"
#: Line style of each configuration, in campaign order (colours C0, C1, ... beside them):
#: the first wide and solid underneath, the others dashed or dotted over it.
STYLES = ("-", "--", ":", "-.")


def style(k: int) -> dict:
    """Colour, line style and width of configuration ``k`` (plot keywords)."""
    return {"color": f"C{k % 10}", "ls": STYLES[k % len(STYLES)],
            "lw": 1.6 if k == 0 else 1.0}
_OFF_SCALE = 4.0   # a requirement this many times the trace's range is written, not drawn


@dataclass(frozen=True)
class Marking:
    """What the figures mark: the budget metric, its window and the requirements.

    Parameters
    ----------
    metric : str
        Budget metric kind (the worst window is drawn for ``peak_to_peak``).
    window : float or None
        Its window (s).
    requirement : dict
        ``{axis: value}`` in the report unit (NaN or absent: none).
    skip : float
        Transient dropped from every record before the metric (s).
    """

    metric: str
    window: float | None
    requirement: dict = field(default_factory=dict)
    skip: float = 0.0

    @property
    def windowed(self) -> bool:
        return self.metric == "peak_to_peak" and bool(self.window)

    def req(self, axis) -> float:
        v = self.requirement.get(axis)
        return float("nan") if v is None else float(v)


@dataclass(frozen=True)
class Panel:
    """One panel of a figure: an instrument axis in every configuration.

    Parameters
    ----------
    instrument, axis : str
        The line of sight drawn.
    series : list of (str, ndarray, ndarray)
        Configuration label, times (s) and values (rad) per case.
    requirement : float
        In the report unit (NaN: none).
    note : str
        What the panel's title adds (the event's share of the RSS²).
    """

    instrument: str
    axis: str
    series: list
    requirement: float = float("nan")
    note: str = ""

    @property
    def name(self) -> str:
        """``instrument axis``."""
        return f"{self.instrument} {self.axis}"


def worst_window(t, x, window: float, skip: float = 0.0):
    """Start, end and mid-range of the window with the largest peak-to-peak.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s), uniform.
    x : ndarray, shape (n,)
        The record (any unit).
    window : float
        Window duration (s).
    skip : float
        Transient dropped from the start (s).

    Returns
    -------
    (t0, t1, mid, p2p) or None
        Window start and end (s), ``(max + min) / 2`` and ``max − min`` inside it (unit of
        ``x``); None when the record is shorter than the window.
    """
    t, x = np.asarray(t, float), np.asarray(x, float)
    if t.size < 3:
        return None
    dt = float(np.median(np.diff(t)))
    keep = t >= M.skip_start(t[0], skip, dt)
    t, x = t[keep], x[keep]
    n = M.window_samples(window, dt)
    if x.size < n:
        return None
    ranges = M.peak_to_peak_series(x, dt, window)
    i = int(np.argmax(ranges))
    seg = x[i:i + n]
    return float(t[i]), float(t[i + n - 1]), float((seg.max() + seg.min()) / 2), float(
        ranges[i])


def legend_above(ax, handles=None, fontsize=7.5):
    """A legend in a row above the axes (outside them: it never hides data).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        The axes; nothing is drawn when there are no handles.
    handles : list of matplotlib.artist.Artist, optional
        The entries, at most four per row; default the axes' labelled artists.
    fontsize : float
        Size of the legend's text (pt).
    """
    handles = handles if handles is not None else ax.get_legend_handles_labels()[0]
    if handles:
        ax.legend(handles=handles, loc="lower left", bbox_to_anchor=(0.0, 1.01),
                  ncol=min(len(handles), 4), fontsize=fontsize, frameon=False,
                  borderaxespad=0.2)


def _off_scale_note(ax, req, unit):
    ax.text(0.995, 0.97, f"requirement {req:g} {unit}: off this scale", ha="right",
            va="top", transform=ax.transAxes, fontsize=7, color=_REQ)


def history_figure(panels, event, unit, scale, marking: Marking):
    """Line of sight of one event on the axes it dominates, configurations overlaid.

    Parameters
    ----------
    panels : list of Panel
        One per axis drawn.
    event : str
        The dominant event (campaign name).
    unit : str
        Report unit.
    scale : float
        Factor from rad to ``unit``.
    marking : Marking
        Metric, window and skip (the requirements are the panels').

    Returns
    -------
    Figure
    """
    # deferred: plotting only
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    fig = Figure(figsize=(9, 2.0 * len(panels) + 1.3), layout="constrained")
    axs = fig.subplots(len(panels), 1, squeeze=False, sharex=True)[:, 0]
    everything = [s for p in panels for s in p.series]
    t_end = max(float(t[-1]) for _, t, _ in everything)
    t_start = min(float(t[0]) for _, t, _ in everything)
    labels = list(dict.fromkeys(label for label, _, _ in everything))
    handles = [Line2D([], [], label=label, **style(k)) for k, label in enumerate(labels)]
    drawn_req, shaded = set(), False
    for ax, panel in zip(axs, panels):
        req = panel.requirement
        spans, lo_hi = [], []
        for label, t, y in panel.series:
            k = labels.index(label)
            y = np.asarray(y, float) * scale
            ax.plot(t, y, **style(k))
            keep = t >= t[0] + marking.skip
            lo_hi += [float(y[keep].min()), float(y[keep].max())]
            if marking.windowed:
                w = worst_window(t, y, marking.window, marking.skip)
                if w is not None:
                    spans.append((label, f"C{k % 10}", w))
        data_range = (max(lo_hi) - min(lo_hi)) if lo_hi else 0.0
        draw_req = bool(np.isfinite(req)) and req <= _OFF_SCALE * max(data_range, 1e-300)
        for _, color, (t0, t1, mid, _) in spans:
            ax.axvspan(t0, t1, color=color, alpha=0.12, lw=0)
            if draw_req:
                ax.add_patch(Rectangle((t0, mid - req / 2), t1 - t0, req, fill=False,
                                       ec=_REQ, lw=1.1, ls="--", zorder=5))
        shaded |= bool(spans)
        if draw_req and spans:
            drawn_req.add(req)
        if np.isfinite(req) and not draw_req:
            _off_scale_note(ax, req, unit)
        title = f"{panel.name}: {panel.note}" if panel.note else panel.name
        if spans:
            title += (f"\nworst {marking.window:g} s window, peak-to-peak: " + ", ".join(
                f"{label} {w[3]:.3g}" for label, _, w in spans) + f" {unit}")
        ax.set_title(title, fontsize=8, loc="left")
        if marking.skip > 0:
            ax.axvspan(t_start, t_start + marking.skip, color="0.85", alpha=0.5, lw=0)
        ax.set_ylabel(f"{panel.name} ({unit})")
        ax.grid(alpha=0.3)
        ax.set_xlim(t_start, t_end)
    if shaded:
        handles.append(Patch(color="0.5", alpha=0.3,
                             label=f"worst {marking.window:g} s window (its colour)"))
    if drawn_req:
        handles.append(Line2D([], [], color=_REQ, ls="--", lw=1.1,
                              label="requirement " + ", ".join(f"{r:g}" for r in sorted(
                                  drawn_req)) + f" {unit} p-p: band over the worst window"))
    if marking.skip > 0:
        handles.append(Patch(color="0.85", label="transient, not in the metric"))
    fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 3),
               fontsize=7.5, frameon=False)
    axs[-1].set_xlabel("time (s)")
    fig.suptitle(f"Dominant event {event}: " + ", ".join(p.name for p in panels),
                 fontsize=11)
    return fig


def scatter_axes(axes):
    """The two axes of the boresight image plane: roll–pitch when both exist (the
    paper's Fig. 16), else the first two."""
    names = list(axes)
    if "roll" in names and "pitch" in names:
        return "roll", "pitch"
    names.sort(key=lambda a: _ORDER.get(a, 3))
    return names[0], names[1]


def joint_worst_window(t, xy, reqs, window: float, skip: float = 0.0):
    """The window in which a boresight's two axes come nearest their requirements.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s), uniform.
    xy : (ndarray, ndarray)
        The two axes, shape (n,) each (report unit).
    reqs : (float, float)
        Their peak-to-peak requirements (NaN: rank by the range itself).
    window : float
        Window duration (s).
    skip : float
        Transient dropped from the start (s).

    Returns
    -------
    slice or None
        The samples of the window whose larger ratio ``range / requirement`` is the
        largest; None when the record is shorter than the window.
    """
    t = np.asarray(t, float)
    if t.size < 3:
        return None
    dt = float(np.median(np.diff(t)))
    first = int(np.searchsorted(t, M.skip_start(t[0], skip, dt)))
    n = M.window_samples(window, dt)
    if t.size - first < n:
        return None
    score = None
    for v, req in zip(xy, reqs):
        r = M.peak_to_peak_series(np.asarray(v, float)[first:], dt, window)
        r = r / req if np.isfinite(req) and req > 0 else r
        score = r if score is None else np.maximum(score, r)
    i = first + int(np.argmax(score))
    return slice(i, i + n)


def scatter_figure(series, inst, event, unit, scale, pair, marking: Marking):
    """Boresight in the image plane (two axes) over each configuration's worst window.

    The budget metric's window in which either axis comes nearest its requirement, for
    each configuration, with the requirement's box (each axis's peak-to-peak
    requirement) centred on the trace's mid-ranges in that window: the trace leaves
    the box exactly when the window fails.  Without a windowed metric, the whole record
    after the transient, the box centred on it.

    Parameters
    ----------
    series : list of (str, ndarray, dict)
        Configuration label, times (s) and ``{axis: values (rad)}`` per case.
    inst, event : str
    unit : str
    scale : float
    pair : (str, str)
        Horizontal and vertical axis.
    marking : Marking

    Returns
    -------
    Figure
    """
    fig = Figure(figsize=(6, 5.8), layout="constrained")
    ax = fig.subplots()
    reqs = [marking.req(a) for a in pair]
    boxes, extent = [], []
    for k, (label, t, cols) in enumerate(series):
        if pair[0] not in cols or pair[1] not in cols:
            continue
        xy = [np.asarray(cols[a], float) * scale for a in pair]
        win = (joint_worst_window(t, xy, reqs, marking.window, marking.skip)
               if marking.windowed else None)
        if win is None:
            win = t >= t[0] + marking.skip
        xy = [v[win] for v in xy]
        st = style(k)
        ax.plot(xy[0], xy[1], color=st["color"], ls=st["ls"], lw=0.9, alpha=0.9,
                label=label + (f", worst {marking.window:g} s window" if marking.windowed
                               else ""))
        extent.append(max(float(np.ptp(v)) for v in xy))
        boxes.append((st["color"], [float((v.max() + v.min()) / 2) for v in xy]))
    if boxes and all(np.isfinite(reqs)):
        if max(reqs) <= _OFF_SCALE * max(max(extent), 1e-300):
            for j, (color, centre) in enumerate(boxes):
                ax.add_patch(Rectangle((centre[0] - reqs[0] / 2, centre[1] - reqs[1] / 2),
                                       reqs[0], reqs[1], fill=False, ec=color, lw=1.2,
                                       ls="--", label=(f"requirement {reqs[0]:g} × "
                                                       f"{reqs[1]:g} {unit} p-p, centred "
                                                       "on each window" if j == 0 else None)))
        else:
            _off_scale_note(ax, max(reqs), unit)
    ax.set_xlabel(f"{pair[0]} ({unit})")
    ax.set_ylabel(f"{pair[1]} ({unit})")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        ax.legend(handles, labels, loc="lower left", bbox_to_anchor=(0.0, 1.01), ncol=1,
                  fontsize=7.5, frameon=False)
    fig.suptitle(f"{inst} boresight, {pair[0]}–{pair[1]} plane: {event}", fontsize=10)
    return fig


def frf_figure(path: Path):
    """Magnitudes of the frequency responses in one ``frf/`` file (log-log).

    Parameters
    ----------
    path : Path
        Parquet or CSV with a ``frequency`` column (Hz) and magnitude columns, or complex
        ones as ``NAME.re`` / ``NAME.im`` pairs.

    Returns
    -------
    Figure
    """
    t = pq.read_table(path) if path.suffix == ".parquet" else pacsv.read_csv(path)
    cols = {n: t.column(n).to_numpy() for n in t.column_names}
    fcol = next((n for n in cols if n.lower() in ("frequency", "frequency_hz", "f", "freq")),
                None)
    if fcol is None:
        raise ReportError(f"FRF file {path.name} has no 'frequency' column (Hz)")
    f = np.asarray(cols.pop(fcol), dtype=float)
    curves = {}
    for n in list(cols):
        if n.endswith(".re") and n[:-3] + ".im" in cols:
            curves[n[:-3]] = np.abs(cols[n] + 1j * cols[n[:-3] + ".im"])
        elif not n.endswith(".im"):
            curves[n] = np.abs(np.asarray(cols[n], dtype=float))
    fig = Figure(figsize=(8, 4), layout="constrained")
    ax = fig.subplots()
    for n, mag in curves.items():
        ax.loglog(f[f > 0], mag[f > 0], lw=1, label=n)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("magnitude")
    ax.grid(which="both", alpha=0.3)
    legend_above(ax)
    fig.suptitle(path.stem.replace("_", " "), fontsize=10)
    return fig
