"""Sweep and spectrum figures: jitter versus a swept quantity, closed-loop transfers.

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

from .analysis.spectra import cumulative_rms
from .metrics import one_sided_psd
from .report_budget import _plain_log_labels
from .report_verdict import metric_words

__all__ = [
    "WORST_HEAD",
    "spectrum_figure",
    "sweep_sections",
    "plan_units",
    "transfer_figure",
    "uncertainty_sections",
    "wheel_verdicts",
]

WORST_HEAD = ["sweep", "configuration", "instrument", "axis", "metric", "worst at", "value",
              "requirement", "margin"]


def _fmt(v, digits=4):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    return f"{v:.{digits}g}"


_ORDER = {"roll": 0, "pitch": 1, "yaw": 2}
#: Share of the cumulative RMS below the end of a spectrum's frequency axis (/1.5).
_CONTENT = 0.995


def _figure(curves, inst, axes, xlabel, unit, title, at="{:.4g}"):
    """One panel per axis; ``curves[axis] = [(label, x, y, requirement)]``; ``at`` formats
    the worst point's abscissa with its unit (``"{:.0f} rpm"``)."""
    axes = sorted(axes, key=lambda a: _ORDER.get(a, 3))
    fig = Figure(figsize=(10, 1.9 * len(axes) + 0.9), layout="constrained")
    axs = fig.subplots(len(axes), 1, squeeze=False, sharex=True)
    for i, axis in enumerate(axes):
        ax = axs[i][0]
        reqs = set()
        for label, x, y, req in curves.get(axis, []):
            k = int(np.argmax(y))
            line, = ax.plot(x, y, lw=1.0,
                            label=f"{label}: worst {y[k]:.3g} {unit} at {at.format(x[k])}")
            ax.plot(x[k], y[k], "o", color=line.get_color(), ms=5)
            if not math.isnan(req):
                reqs.add(req)
        for req in sorted(reqs):
            ax.axhline(req, color="crimson", ls="--", lw=1.0,
                       label=f"requirement {req:g} {unit}")
        peak = max((float(np.max(y)) for _, _, y, _ in curves.get(axis, [])), default=0.0)
        if reqs and peak > 0 and max(reqs) > 10 * peak:
            ax.set_yscale("log")   # a requirement far above the curves: keep both visible
            ax.set_ylim(bottom=peak * 1e-3)
        ax.set_ylabel(f"{axis} ({unit})")
        ax.grid(alpha=0.3)
        # beside the panel (worst points in the labels): nothing drawn over the curves
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.005, 1.0), frameon=False)
    axs[-1][0].set_xlabel(xlabel)
    fig.suptitle(f"{inst}: {title}", fontsize=11)
    return fig


def _add_curve(curves, worst, where, x, y, req, at):
    """One configuration's curve of a panel and its worst point (a row of WORST_HEAD)."""
    sweep, cf, inst, axis, metric = where
    curves.setdefault(axis, []).append((cf, x, y, req))
    k = int(np.argmax(y))
    worst.append([sweep, cf, inst, axis, metric, at.format(x[k]), _fmt(y[k]), _fmt(req),
                  _fmt(req - y[k]) if not math.isnan(req) else ""])


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
                    _add_curve(curves, worst, (sweep, cf, inst, axis, metric), x, y,
                               sel[0]["requirement"], "{:.0f} rpm")
            if curves:
                figures.append((f"{inst}: {sweep}, steady state",
                                _figure(curves, inst, list(axes), "wheel speed (rpm)", unit,
                                        f"{sweep} (steady state, {metric_words(metric, window)})",
                                        "{:.0f} rpm")))
    return figures, worst


def _numeric(text):
    try:
        return float(text)
    except ValueError:
        return None


def _parameter(summary, instruments, metric, window, unit, rss_event, units):
    """RSS rows against a single numeric swept parameter (``sweep = "p=v"``), its axis
    and worst points in the unit its FMU declares (``units[p]``, when known)."""
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
        u = units.get(param, "")
        at = f"{param} = {{:.4g}}" + (f" {u}" if u else "")
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
                    _add_curve(curves, worst, (param, cf, inst, axis, metric), x, y,
                               sel[0][1]["requirement"], at)
            if curves:
                figures.append((f"{inst}: RSS against {param}",
                                _figure(curves, inst, list(axes),
                                        f"{param} ({u})" if u else param, unit,
                                        f"RSS over the events against {param} "
                                        f"({metric_words(metric, window)})", at)))
    return figures, worst


def wheel_verdicts(out_dir, metric, window):
    """The verdict of a campaign's wheel sweeps: per instrument axis, the worst speed.

    Parameters
    ----------
    out_dir : path-like
        The campaign folder (``wheel_sweeps.parquet``).
    metric : str
        Budget metric kind.
    window : float or None
        Its window (s).

    Returns
    -------
    configurations : list of str
    lines : list of AxisVerdict
        Per instrument and axis, each configuration's largest steady-state value over
        every sweep and speed (``sweep`` says which, ``"RWA speed at 5255 rpm"``),
        against the requirement; no dominant event (a sweep has one source).
    """
    from .report_verdict import AxisVerdict

    path = Path(out_dir) / "wheel_sweeps.parquet"
    if not path.is_file():
        return [], []
    rows = [r for r in pq.read_table(path).to_pylist() if r["metric"] == metric
            and (window is None or r["window"] is None or math.isclose(r["window"], window))]
    configs = list(dict.fromkeys(r["configuration"] for r in rows))
    lines = []
    for inst, axis in dict.fromkeys((r["instrument"], r["axis"]) for r in rows):
        vals, where, passed, req = [], [], [], math.nan
        for cf in configs:
            mine = [r for r in rows if (r["instrument"], r["axis"], r["configuration"])
                    == (inst, axis, cf) and r["value"] == r["value"]]
            if not mine:
                vals.append(math.nan), where.append(""), passed.append(None)
                continue
            worst = max(mine, key=lambda r: r["value"])
            vals.append(worst["value"])
            where.append(f"{worst['sweep']} at {worst['rpm']:.0f} rpm")
            r_ = worst["requirement"]
            req = r_ if r_ is not None and r_ == r_ else req
            passed.append(None if req != req else bool(worst["value"] <= req))
        lines.append(AxisVerdict(inst, axis, tuple(vals), tuple(where), req, tuple(passed),
                                 (None,) * len(configs)))
    return configs, lines


def sweep_sections(out_dir, summary, instruments, metric, window, unit, rss_event,
                   sweep_units=None):
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
    sweep_units : dict of str to str, optional
        Unit of each swept parameter (``campaign.json``'s ``sweep_units``).

    Returns
    -------
    figures : list of (str, Figure)
    worst : list of list of str
        Rows of :data:`WORST_HEAD`.
    """
    f1, w1 = _wheel(Path(out_dir), instruments, metric, window, unit)
    f2, w2 = _parameter(summary, instruments, metric, window, unit, rss_event,
                        sweep_units or {})
    return f1 + f2, w1 + w2


def plan_units(plan, names) -> dict:
    """The units the FMUs declare for ``instance.variable`` names (``""`` for none).

    Parameters
    ----------
    plan : orchestrator.cosim.Plan
        A prepared scenario (``linearize(...).plan``).
    names : iterable of str
        ``instance.variable`` names.

    Returns
    -------
    dict of str to str
    """
    out = {}
    for name in names:
        inst, _, var = name.partition(".")
        v = plan.fmus[inst].variables.get(var) if inst in plan.fmus else None
        out[name] = (v.unit or "") if v is not None else ""
    return out


def _ratio(num: str, den: str) -> str:
    """A transfer's unit: ``rad/V``; ``1`` stands for no unit."""
    num, den = num or "1", den or "1"
    return num if den == "1" else f"{num}/{den}"


def transfer_figure(tr, psd=None, cum=None, units=None) -> Figure:
    """Magnitudes of closed-loop transfers (and output PSD, cumulative RMS).

    Parameters
    ----------
    tr : orchestrator.analysis.spectra.Transfer
    psd, cum : ndarray, shape (n_out, n_f), optional
        Output PSD and its cumulative RMS (:func:`~orchestrator.analysis.spectra.output_psd`).
    units : dict of str to str, optional
        Unit of each input and output as the FMUs declare it (:func:`plan_units`); the
        axes and legends give them.

    Returns
    -------
    Figure
    """
    units = units or {}
    out_units = {units.get(o, "") or "1" for o in tr.outputs}
    one = out_units.pop() if len(out_units) == 1 else None   # one unit for every output
    pairs = {_ratio(units.get(o, ""), units.get(s, "")) for o in tr.outputs for s in tr.inputs}
    rows = 1 if psd is None else 3
    fig = Figure(figsize=(9, 2.6 * rows + 0.8))
    axs = fig.subplots(rows, 1, squeeze=False, sharex=True)
    ax = axs[0][0]
    for i, o in enumerate(tr.outputs):
        for j, src in enumerate(tr.inputs):
            unit = "" if len(pairs) == 1 else f" ({_ratio(units.get(o, ''), units.get(src, ''))})"
            ax.loglog(tr.freqs, np.abs(tr.H[i, j]), lw=0.9, label=f"{src} -> {o}{unit}")
    ax.set_ylabel(f"|H| ({pairs.pop()})" if len(pairs) == 1 else "|H| (units in legend)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=6, loc="lower left", ncol=2)
    if psd is not None:
        for i, o in enumerate(tr.outputs):
            label = o if one else f"{o} ({units.get(o, '') or '1'})"
            axs[1][0].loglog(tr.freqs, np.maximum(psd[i], 1e-300), lw=0.9, label=label)
            axs[2][0].semilogx(tr.freqs, cum[i], lw=0.9, label=label)
        axs[1][0].set_ylabel(f"PSD ({one}²/Hz)" if one else "PSD (unit²/Hz, in legend)")
        axs[2][0].set_ylabel(f"cumulative RMS ({one})" if one else
                             "cumulative RMS (unit in legend)")
        for a in (axs[1][0], axs[2][0]):
            a.grid(alpha=0.3, which="both")
        axs[2][0].legend(fontsize=6, loc="upper left")
    axs[-1][0].set_xlabel("frequency (Hz)")
    fig.suptitle("closed-loop transfer (fundamental of the steady state)", fontsize=11)
    fig.tight_layout()
    return fig


def spectrum_figure(panels, event, unit, scale, skip: float) -> Figure:
    """One-sided PSD and cumulative RMS of recorded lines of sight.

    The record after ``skip`` s, Welch's estimate with one Hann segment over it
    (:func:`orchestrator.metrics.one_sided_psd`), the cumulative RMS its running integral
    (its end is about the record's RMS).  The frequency axis ends at 1.5 times the
    highest frequency where a curve's cumulative RMS reaches 99.5 % of its end (at most
    the Nyquist frequency): what holds the content spans the axis, not a flat line.

    Parameters
    ----------
    panels : list of Panel
        One row per instrument axis (:class:`orchestrator.report_figures.Panel`).
    event : str
        The event named in the title.
    unit : str
        Unit of the axes.
    scale : float
        Factor from rad to ``unit``.
    skip : float
        Transient dropped (s).

    Returns
    -------
    Figure
    """
    from .report_figures import style

    fig = Figure(figsize=(9, 2.2 * len(panels) + 1.1), layout="constrained")
    axs = fig.subplots(len(panels), 2, squeeze=False, sharex=True)
    labels = list(dict.fromkeys(label for p in panels for label, _, _ in p.series))
    f_lo, f_hi, nyquist, spectra = math.inf, 0.0, 0.0, []
    for i, panel in enumerate(panels):
        for label, t, y in panel.series:
            if t.size < 8:
                continue
            st = style(labels.index(label))
            keep = t >= t[0] + skip - 1e-9
            x = np.asarray(y, float)[keep] * scale
            dt = float(np.median(np.diff(t)))
            # one Hann segment over the record: the finest resolution it has (a jitter
            # record is a few periods of its slowest motion; four segments lost them)
            f, psd = one_sided_psd(x, dt, x.size * dt)
            cum = cumulative_rms(f, psd)
            axs[i][0].loglog(f[1:], np.maximum(psd[1:], 1e-300), label=label, **st)
            spectra.append((i, f, psd))
            axs[i][1].semilogx(f[1:], cum[1:], label=label, **st)
            f_lo, nyquist = min(f_lo, float(f[1])), max(nyquist, float(f[-1]))
            if cum[-1] > 0:
                f_hi = max(f_hi, float(f[int(np.searchsorted(cum, _CONTENT * cum[-1]))]))
        axs[i][1].set_ylim(bottom=0.0)   # the share of each band reads off a zero base
        axs[i][0].set_ylabel(f"{panel.name} ({unit}²/Hz)")
        axs[i][1].set_ylabel(f"cum. RMS ({unit})")
        for a in axs[i]:
            a.grid(alpha=0.3, which="both")
    if math.isfinite(f_lo) and f_hi > 0:
        f_top = min(max(1.5 * f_hi, 4 * f_lo), nyquist)
        axs[0][0].set_xlim(f_lo, f_top)
        for i in range(len(panels)):   # the PSD's scale from what the axis shows
            seen = np.concatenate([p[(f >= f_lo) & (f <= f_top)] for j, f, p in spectra
                                   if j == i] or [np.zeros(0)])
            seen = seen[seen > 0]
            if seen.size:
                axs[i][0].set_ylim(max(seen.min(), seen.max() * 1e-8) / 2, seen.max() * 2)
        for a in axs[-1]:
            _plain_log_labels(a.xaxis, f_lo, f_top)
    handles, names = axs[0][1].get_legend_handles_labels()
    fig.legend(handles, names, loc="outside lower center", ncol=min(len(names), 4),
               fontsize=7.5, frameon=False)   # below the panels: never over a curve
    for a in axs[-1]:
        a.set_xlabel("frequency (Hz)")
    fig.suptitle(f"Dominant event {event}: PSD and cumulative RMS of "
                 + ", ".join(p.name for p in panels), fontsize=11)
    return fig


def strongest(correlations: dict, k: int) -> list:
    """The ``k`` names of largest ``|correlation|``, largest first (``uncertainty.json``
    keeps its tables sorted by name).

    Parameters
    ----------
    correlations : dict of str to float
        Input name -> rank correlation (``sensitivity``, ``drivers``).
    k : int
        How many names.

    Returns
    -------
    list of str
    """
    return sorted(correlations, key=lambda name: (-abs(correlations[name]), name))[:k]


def _sensitivity_bars(ax, line: dict) -> None:
    """The six inputs that explain most of a line's budget (first-order index, bars),
    each with its rank correlation; a file without indices shows the correlations."""
    sens, first = line.get("sensitivity", {}), line.get("first_order")
    if first:
        names = sorted(first, key=lambda k: (-first[k], k))[:6][::-1]
        vals, lim = [max(first[n], 0.0) for n in names], (0, 1)
        title = "share explained alone, rank corr. at right"
    else:
        names = strongest(sens, 6)[::-1]
        vals, lim = [sens[n] for n in names], (-1, 1)
        title = "rank correlation"
    ax.barh(range(len(names)), vals, color="0.45", height=0.6)
    if first:
        for k, n in enumerate(names):
            if n in sens:
                ax.text(0.98, k, f"{sens[n]:+.2f}", ha="right", va="center", fontsize=6,
                        transform=ax.get_yaxis_transform())
    ax.set_yticks(range(len(names)), names, fontsize=7)
    pad = max(4 - len(names), 0) / 2       # one bar stays a bar, centred
    ax.set_ylim(-0.5 - pad, len(names) - 0.5 + pad)
    ax.set_xlim(*lim)
    ax.axvline(0, color="k", lw=0.5)
    ax.set_title(f"{title} ({line['configuration']})", fontsize=7)


def uncertainty_sections(out_dir, instruments, unit):
    """CDF and sensitivity figures of ``uncertainty.json``, and its table rows.

    Parameters
    ----------
    out_dir : path-like
        The campaign folder.
    instruments : dict
        ``{instrument: {axis: variable}}``.
    unit : str
        Unit of the values.

    Returns
    -------
    figures : list of (str, Figure)
    rows : list of list of str
        ``configuration, instrument, axis, metric, P_c, value, bootstrap interval,
        converged, upper bound, requirement, P(meet), its lower bound``.
    text : str
        The interpretation and sample count, or "" without an uncertainty run.
    """
    import json

    from .campaign.mcloop import path_lines
    from .campaign.mcresults import unbounded_words

    out_dir = Path(out_dir)
    path = out_dir / "uncertainty.json"
    samples_path = out_dir / "uncertainty_samples.parquet"
    if not path.is_file() or not samples_path.is_file():
        return [], [], ""
    rep = json.loads(path.read_text(encoding="utf-8"))
    table = pq.read_table(samples_path, columns=["configuration", "instrument", "axis",
                                                  "metric", "value"])
    # the samples of each line (configuration, instrument, axis, metric), by column:
    # a run extended to tens of thousands of samples has millions of rows
    keys = list(zip(*(table[c].to_pylist() for c in ("configuration", "instrument", "axis",
                                                      "metric"))))
    values = table["value"].to_numpy(zero_copy_only=False)
    index = {}
    for j, key in enumerate(keys):
        index.setdefault(key, []).append(j)
    figures, rows = [], []
    first_metric = rep["lines"][0]["metric"] if rep["lines"] else None
    for inst, axes in instruments.items():
        axes = sorted(axes, key=lambda a: _ORDER.get(a, 3))
        fig = Figure(figsize=(9, 2.0 * len(axes) + 0.9))
        axs = fig.subplots(len(axes), 2, squeeze=False,
                           gridspec_kw={"width_ratios": [3, 2]})
        for i, axis in enumerate(axes):
            lines = [ln for ln in rep["lines"] if ln["instrument"] == inst
                     and ln["axis"] == axis and ln["metric"] == first_metric]
            for ln in lines:
                allx = values[index.get((ln["configuration"], inst, axis, first_metric),
                                        [])]
                x = np.sort(allx[np.isfinite(allx)])   # inf: unstable, never below a bound
                if x.size == 0:
                    continue
                cdf = np.arange(1, x.size + 1) / allx.size
                line, = axs[i][0].step(x, cdf, where="post", lw=1.0,
                                       label=ln["configuration"])
                for pc, q in ln.get("quantiles", {}).items():
                    axs[i][0].plot([q["value"]], [float(pc)], "o", ms=4,
                                   color=line.get_color())
                    rows.append([ln["configuration"], inst, axis, first_metric,
                                 f"{100 * float(pc):g} %",
                                 _fmt(q["value"]) if math.isfinite(q["value"])
                                 else unbounded_words(ln),
                                 f"[{_fmt(q['low'])}, {_fmt(q['high'])}]",
                                 "yes" if q["converged"] else "no" + (
                                     f" (about {q['samples_for_2pct']} samples)"
                                     if q.get("samples_for_2pct") else ""),
                                 _bound_cell(q, ln.get("assurance")),
                                 _fmt(ln.get("requirement")),
                                 _fmt(ln.get("p_meet"), 3), _fmt(ln.get("p_meet_low"), 3)])
                    if q.get("upper_rank") is not None and math.isfinite(q["upper_bound"]):
                        axs[i][0].plot([q["upper_bound"]], [float(pc)], ">", ms=5,
                                       mfc="none", color=line.get_color())
                req = ln.get("requirement")
                if req is not None and not math.isnan(req):
                    axs[i][0].axvline(req, color="crimson", ls="--", lw=1.0)
            if lines:
                _sensitivity_bars(axs[i][1], lines[-1])
            shown = [ln.get_xdata() for ln in axs[i][0].get_lines()]
            shown = np.concatenate([np.ravel(x) for x in shown]) if shown else np.array([])
            shown = shown[np.isfinite(shown) & (shown > 0)]
            if shown.size and shown.max() > 10 * shown.min():
                axs[i][0].set_xscale("log")   # configurations a decade apart: both readable
                _plain_log_labels(axs[i][0].xaxis, shown.min(), shown.max())
            axs[i][0].set_ylabel(f"{axis}: P(X <= x)")
            axs[i][0].grid(alpha=0.3)
        axs[0][0].legend(fontsize=7, loc="lower right")
        axs[-1][0].set_xlabel(f"RSS over the events ({unit})\ndashed: requirement; dot: "
                              "value at P_c; triangle: its upper bound", fontsize=8)
        fig.suptitle(f"{inst}: budget distribution over {rep['samples']} samples", fontsize=11)
        fig.tight_layout()
        figures.append((f"{inst}: budget distribution", fig))
    text = (f"{rep['samples']} samples (seed {rep['seed']}), linear engine; "
            f"interpretation: {rep['interpretation']}; converged: the 95 % bootstrap "
            "interval of the value is narrower than 2 % of it" + (
                f"; {rep['bounds']} (assurance {rep['assurance']:g})"
                if rep.get("bounds") else "") + ".")
    drivers = rep.get("drivers") or {}

    def most(key, cf):   # the input most related to a status, in words
        d = (drivers.get(key) or {}).get(cf) or {}
        if not d:
            return ""
        name = strongest(d, 1)[0]
        return f"; most related input: {name}, rank correlation {d[name]:+.2f}"

    for cf, k in (rep.get("unstable") or {}).items():
        lim = (rep.get("limit_reached") or {}).get(cf, 0)
        fast = (rep.get("diverging_in_record") or {}).get(cf, 0)
        if k or lim:
            text += (f" {cf}: {k} sample(s) with an unstable closed loop ({fast} doubling "
                     f"within the record{most('unstable', cf)}) and {lim} whose record "
                     f"reached a rail or limit{most('limit_reached', cf)}, all counted as "
                     "exceeding every requirement (the CDF stops below 1; the records of "
                     "the unstable ones, as the co-simulation would give them, are the "
                     "record_value of uncertainty_samples.parquet).")
    text += _leaders(rep.get("lines", []))
    text += "".join(f" {line.strip()}." for line in path_lines(rep.get("linear_engine") or {}))
    return figures, rows, text


def _bound_cell(q: dict, assurance) -> str:
    """A level's upper bound for the table: the value and its assurance, or the sample
    count a bound needs; "" for a file written before bounds."""
    if assurance is None or "upper_bound" not in q:
        return ""
    if q.get("upper_rank") is None:
        return f"needs {q['samples_for_bound']} samples"
    return f"{_fmt(q['upper_bound'])} ({100 * assurance:g} %)"


def _leaders(lines) -> str:
    """Per configuration, the input that explains the largest share of a line's budget
    alone (first-order index), in words; nothing for a file without indices."""
    best = {}
    for ln in lines:
        for name, share in (ln.get("first_order") or {}).items():
            cf = ln["configuration"]
            if share > best.get(cf, (None, 0.0))[1]:
                best[cf] = (name, share, f"{ln['instrument']} {ln['axis']}",
                            (ln.get("sensitivity") or {}).get(name))
    out = ""
    for cf, (name, share, where, rho) in best.items():
        corr = "" if rho is None else f", rank correlation {rho:+.2f}"
        out += (f" {cf}: the input that explains most of a budget alone is {name} "
                f"({100 * share:.0f} % of the spread of {where}{corr}).")
    return out
