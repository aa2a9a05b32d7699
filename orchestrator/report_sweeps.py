"""Sweep figures and tables of a campaign report: jitter versus a swept quantity.

Two kinds of sweep reach the report:

* a campaign's ``[[wheel_sweeps]]`` (``wheel_sweeps.parquet``): steady-state jitter
  over a wheel's speed range, one curve per configuration;
* a campaign's ``[[sweeps]]`` over a numeric parameter: the RSS over the events of each
  configuration at every swept value, from the summary.

Each gives one figure per instrument (a panel per axis) with the requirement as a line
and the worst point of every curve marked, and a table of the worst points.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
from matplotlib.figure import Figure

__all__ = ["WORST_HEAD", "sweep_sections"]

WORST_HEAD = ["sweep", "configuration", "instrument", "axis", "metric", "worst at", "value",
              "requirement", "margin"]


def _fmt(v, digits=4):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    return f"{v:.{digits}g}"


_ORDER = {"roll": 0, "pitch": 1, "yaw": 2}


def _figure(curves, inst, axes, xlabel, unit, title):
    """One panel per axis; ``curves[axis] = [(label, x, y, requirement)]``."""
    axes = sorted(axes, key=lambda a: _ORDER.get(a, 3))
    fig = Figure(figsize=(9, 1.9 * len(axes) + 0.9))
    axs = fig.subplots(len(axes), 1, squeeze=False, sharex=True)
    for i, axis in enumerate(axes):
        ax = axs[i][0]
        reqs = set()
        for label, x, y, req in curves.get(axis, []):
            line, = ax.plot(x, y, lw=1.0, label=label)
            k = int(np.argmax(y))
            ax.plot(x[k], y[k], "o", color=line.get_color(), ms=5)
            ax.annotate(f"{y[k]:.3g} at {x[k]:.4g}", (x[k], y[k]), fontsize=7,
                        xytext=(4, 4 + 9 * len(ax.texts)), textcoords="offset points")
            if not math.isnan(req):
                reqs.add(req)
        for req in sorted(reqs):
            ax.axhline(req, color="crimson", ls="--", lw=1.0, label=f"requirement {req:g}")
        peak = max((float(np.max(y)) for _, _, y, _ in curves.get(axis, [])), default=0.0)
        if reqs and peak > 0 and max(reqs) > 10 * peak:
            ax.set_yscale("log")   # a requirement far above the curves: keep both visible
            ax.set_ylim(bottom=peak * 1e-3)
        ax.set_ylabel(f"{axis} ({unit})")
        ax.grid(alpha=0.3)
        if i == 0:
            ax.legend(fontsize=7, loc="upper left")
    axs[-1][0].set_xlabel(xlabel)
    fig.suptitle(f"{inst}: {title}", fontsize=11)
    fig.tight_layout()
    return fig


def _wheel(out_dir: Path, instruments, metric, window, unit):
    path = out_dir / "wheel_sweeps.parquet"
    if not path.is_file():
        return [], []
    rows = [r for r in pq.read_table(path).to_pylist() if r["metric"] == metric
            and (window is None or r["window"] is None or math.isclose(r["window"], window))]
    figures, worst = [], []
    for sweep in dict.fromkeys(r["sweep"] for r in rows):
        for inst, axes in instruments.items():
            curves = {}
            for axis in axes:
                for cf in dict.fromkeys(r["configuration"] for r in rows):
                    sel = [r for r in rows if (r["sweep"], r["instrument"], r["axis"],
                                               r["configuration"]) == (sweep, inst, axis, cf)]
                    if not sel:
                        continue
                    x = np.array([r["rpm"] for r in sel])
                    y = np.array([r["value"] for r in sel])
                    req = sel[0]["requirement"]
                    curves.setdefault(axis, []).append((cf, x, y, req))
                    k = int(np.argmax(y))
                    worst.append([sweep, cf, inst, axis, metric, f"{x[k]:.0f} rpm",
                                  _fmt(y[k]), _fmt(req),
                                  _fmt(req - y[k]) if not math.isnan(req) else ""])
            if curves:
                figures.append((f"{inst}: {sweep}, steady state",
                                _figure(curves, inst, list(axes), "wheel speed (rpm)", unit,
                                        f"{sweep} (steady state, {metric})")))
    return figures, worst


def _numeric(text):
    try:
        return float(text)
    except ValueError:
        return None


def _parameter(summary, instruments, metric, window, unit, rss_event):
    """RSS rows against a single numeric swept parameter (``sweep = "p=v"``)."""
    rows = [r for r in summary if r["event"] == rss_event and r["sweep"]
            and r["metric"] == metric
            and (window is None or r["window"] is None or math.isclose(r["window"], window))]
    points = {}
    for r in rows:
        parts = [p.partition("=") for p in r["sweep"].split(", ")]
        if len(parts) != 1 or _numeric(parts[0][2]) is None:
            continue   # several swept parameters, or a non-numeric one: the table has them
        points.setdefault(parts[0][0], []).append((_numeric(parts[0][2]), r))
    figures, worst = [], []
    for param, pts in points.items():
        for inst, axes in instruments.items():
            curves = {}
            for axis in axes:
                for cf in dict.fromkeys(r["configuration"] for _, r in pts):
                    sel = sorted((x, r) for x, r in pts if (r["instrument"], r["axis"],
                                                            r["configuration"])
                                 == (inst, axis, cf))
                    if len(sel) < 2:
                        continue
                    x = np.array([p for p, _ in sel])
                    y = np.array([r["value"] for _, r in sel])
                    req = sel[0][1]["requirement"]
                    curves.setdefault(axis, []).append((cf, x, y, req))
                    k = int(np.argmax(y))
                    worst.append([param, cf, inst, axis, metric, f"{param} = {x[k]:.4g}",
                                  _fmt(y[k]), _fmt(req),
                                  _fmt(req - y[k]) if not math.isnan(req) else ""])
            if curves:
                figures.append((f"{inst}: RSS against {param}",
                                _figure(curves, inst, list(axes), param, unit,
                                        f"RSS over the events against {param} ({metric})")))
    return figures, worst


def sweep_sections(out_dir, summary, instruments, metric, window, unit, rss_event):
    """Figures ``[(title, Figure)]`` and worst-point rows of every sweep of a campaign.

    Parameters
    ----------
    out_dir : path-like
        The campaign folder (``wheel_sweeps.parquet`` is read from it when present).
    summary : list of dict
        Summary rows (values in ``unit``).
    instruments : dict
        ``{instrument: {axis: variable}}``.
    metric : str
        Metric kind drawn.
    window : float or None
        Its window (s).
    unit : str
        Unit of the values.
    rss_event : str
        Event name of the RSS rows.

    Returns
    -------
    figures : list of (str, Figure)
    worst : list of list of str
        Rows of :data:`WORST_HEAD`.
    """
    f1, w1 = _wheel(Path(out_dir), instruments, metric, window, unit)
    f2, w2 = _parameter(summary, instruments, metric, window, unit, rss_event)
    return f1 + f2, w1 + w2
