"""Campaign reports: jitter budget charts, time histories, boresight scatter, FRFs, tables.

:func:`write_report` reads a campaign output folder (see :mod:`orchestrator.campaign`) and
writes either one self-contained HTML file (figures embedded as base64 PNG) or a Markdown
file with PNG figures next to it.  Contents:

1. Budget chart (Fig. 8 style), one figure for all configurations so that they compare
   at a glance: the RSS total of every instrument and axis with one bar per
   configuration side by side on a log axis and the requirement across each group;
   below, a heat map of every event x instrument-axis in the first configuration (log
   colours, values in the cells) and one of each further configuration's change against
   it (%).  The budget metric is the metric and window of the first requirement (or the
   first metric).
2. Time histories of the dominant case of every instrument (the event with the largest
   share of the RSS), all configurations overlaid.
3. Boresight image-plane scatter (Fig. 16 style) of the dominant case of every instrument
   with at least two axes (pitch against yaw when present), configurations overlaid.
4. Frequency responses / transmissibilities found in ``DIR/frf/*.parquet`` or ``*.csv``:
   a ``frequency`` column (Hz) and magnitude columns, or complex ones as ``NAME.re`` and
   ``NAME.im`` pairs; plotted as magnitudes on log-log axes.
5. The budget table (RSS rows with their change against the first configuration,
   requirement, margin, margin %, pass and dominant event), the failed cases, and every
   summary row.

Figures are drawn with matplotlib's Agg canvas (no display needed, the global backend is
left alone).
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
from pathlib import Path

import numpy as np
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .campaign import ANGLE_UNITS, RSS_EVENT, slug
from .report_budget import BudgetGrid, _budget_figure, _group_label, _groups, budget_grid
from .report_sweeps import WORST_HEAD, spectrum_figure, sweep_sections, uncertainty_sections

UNC_HEAD = ["configuration", "instrument", "axis", "metric", "P_c", "value",
            "bootstrap 95 %", "converged", "requirement", "P(meet)"]

__all__ = ["BudgetGrid", "ReportError", "budget_grid", "write_report"]

FORMATS = ("html", "md")
_MAX_GROUPS = 8  # configuration x sweep groups drawn in one figure


class ReportError(ValueError):
    """A campaign folder that cannot be reported on."""


# ----------------------------------------------------------------------------- data


def _load(out_dir: Path):
    for name in ("campaign.json", "summary.parquet"):
        if not (out_dir / name).is_file():
            raise ReportError(
                f"campaign folder {str(out_dir)!r} has no {name}; run 'jitterfmu campaign' first"
            )
    camp = json.loads((out_dir / "campaign.json").read_text(encoding="utf-8"))
    summary = pq.read_table(out_dir / "summary.parquet").to_pylist()
    cases = (pq.read_table(out_dir / "cases.parquet").to_pylist()
             if (out_dir / "cases.parquet").is_file() else [])
    return camp, summary, cases


def _budget_metric(camp, summary):
    reqs = camp.get("requirements") or []
    for r in reqs:
        if "metric" in r:
            return r["metric"], r.get("window")
    if summary:
        return summary[0]["metric"], summary[0]["window"]
    metrics = camp.get("metrics") or []
    if metrics:
        return metrics[0][0], metrics[0][1]
    return None, None


def _same_window(a, b) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return math.isclose(float(a), float(b))



def png_bytes(fig: Figure) -> bytes:
    """A figure as PNG bytes (Agg canvas, 110 dpi)."""
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return buf.getvalue()


def _dominant(rows, inst):
    """Dominant event of an instrument: the largest share summed over groups and axes."""
    score: dict = {}
    for r in rows:
        if r["instrument"] == inst and r["event"] != RSS_EVENT:
            score[r["event"]] = score.get(r["event"], 0.0) + (r.get("share") or 0.0)
    return max(score, key=score.get) if score else None


def _case_series(out_dir, camp, event, axes):
    """(group label, time, {axis: values in rad}) for every case of an event."""
    out = []
    for c in camp["cases"]:
        if c["event"] != event:
            continue
        path = out_dir / "cases" / c["key"] / "results.parquet"
        if not path.is_file():
            continue
        t = pq.read_table(path)
        names = t.column_names
        tcol = "time" if "time" in names else names[0]
        cols = {a: t.column(v).to_numpy() for a, v in axes.items() if v in names}
        out.append((_group_label((c["configuration"], c["sweep"])) or event,
                    t.column(tcol).to_numpy(), cols))
    return out


def _history_figure(series, inst, event, unit, scale):
    axes = list(series[0][2])
    fig = Figure(figsize=(9, 1.9 * len(axes) + 0.8))
    axs = fig.subplots(len(axes), 1, squeeze=False, sharex=True)
    for i, axis in enumerate(axes):
        ax = axs[i][0]
        for label, t, cols in series:
            if axis in cols:
                ax.plot(t, cols[axis] * scale, lw=0.8, label=label)
        ax.set_ylabel(f"{axis} ({unit})")
        ax.grid(alpha=0.3)
        if i == 0:
            ax.legend(fontsize=7, loc="upper right")
    axs[-1][0].set_xlabel("time (s)")
    fig.suptitle(f"{inst} line of sight, dominant event: {event}", fontsize=11)
    fig.tight_layout()
    return fig


def _scatter_axes(axes):
    names = list(axes)
    if "yaw" in names and "pitch" in names:
        return "yaw", "pitch"
    return names[0], names[1]


def _scatter_figure(series, inst, event, unit, scale, pair):
    fig = Figure(figsize=(5.5, 5))
    ax = fig.subplots()
    for label, _, cols in series:
        if pair[0] in cols and pair[1] in cols:
            ax.plot(cols[pair[0]] * scale, cols[pair[1]] * scale, ".", ms=1.5, alpha=0.6,
                    label=label)
    ax.set_xlabel(f"{pair[0]} ({unit})")
    ax.set_ylabel(f"{pair[1]} ({unit})")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, markerscale=6)
    ax.set_title(f"{inst} boresight in the image plane — {event}", fontsize=10)
    fig.tight_layout()
    return fig


def _frf_files(out_dir: Path):
    d = out_dir / "frf"
    if not d.is_dir():
        return []
    return sorted(p for p in d.iterdir() if p.suffix in (".parquet", ".csv"))


def _frf_figure(path: Path):
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
    fig = Figure(figsize=(8, 4))
    ax = fig.subplots()
    for n, mag in curves.items():
        ax.loglog(f[f > 0], mag[f > 0], lw=1, label=n)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("magnitude")
    ax.grid(which="both", alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(path.stem, fontsize=10)
    fig.tight_layout()
    return fig


# ----------------------------------------------------------------------------- tables


def _fmt(v, digits=4):
    if v is None:
        return ""
    if isinstance(v, bool):
        return "pass" if v else "FAIL"
    if isinstance(v, float):
        if math.isnan(v):
            return ""
        return f"{v:.{digits}g}"
    return str(v)


def _budget_rows(rows, metric, window):
    rss = [r for r in rows if r["event"] == RSS_EVENT and r["metric"] == metric
           and _same_window(r["window"], window)]
    groups = _groups(rss)
    base = {(r["instrument"], r["axis"]): r["value"] for r in rss
            if groups and (r["configuration"], r["sweep"]) == groups[0]}
    # instrument and axis in campaign order, its configurations next to each other
    cols = list(dict.fromkeys((r["instrument"], r["axis"]) for r in rss))
    rss.sort(key=lambda r: (cols.index((r["instrument"], r["axis"])),
                            groups.index((r["configuration"], r["sweep"]))))
    out = []
    for r in rss:
        contrib = [c for c in rows if c["event"] != RSS_EVENT and c["metric"] == metric
                   and _same_window(c["window"], window) and c["instrument"] == r["instrument"]
                   and c["axis"] == r["axis"] and c["configuration"] == r["configuration"]
                   and c["sweep"] == r["sweep"]]
        dom = max(contrib, key=lambda c: c.get("share") or 0.0) if contrib else None
        ratio = r["margin_ratio"]
        b = base.get((r["instrument"], r["axis"]))
        first = (r["configuration"], r["sweep"]) == groups[0]
        change = ("" if first or b is None or r["value"] is None or not b > 0
                  or math.isnan(r["value"]) else f"{100 * (r['value'] - b) / b:+.1f} %")
        out.append([
            r["instrument"], r["axis"], _group_label((r["configuration"], r["sweep"])),
            _fmt(r["value"]), change, _fmt(r["requirement"]), _fmt(r["margin"]),
            "" if ratio is None or math.isnan(ratio) else f"{100 * ratio:.1f} %",
            _fmt(r["pass"]) if r["pass"] is not None else ("n/a" if not r["note"] else "incomplete"),
            "" if dom is None else f"{dom['event']} ({100 * (dom.get('share') or 0):.0f} %)",
        ])
    return out


BUDGET_HEAD = ["instrument", "axis", "configuration", "RSS", "change vs first configuration",
               "requirement", "margin", "margin %", "pass", "dominant event (share)"]
SUMMARY_HEAD = ["case", "instrument", "axis", "metric", "window (s)", "value", "requirement",
                "margin", "pass", "share", "note"]


def _summary_rows(rows):
    return [[r["case"], r["instrument"], r["axis"], r["metric"], _fmt(r["window"]),
             _fmt(r["value"]), _fmt(r["requirement"]), _fmt(r["margin"]),
             _fmt(r["pass"]) if r["pass"] is not None else "",
             _fmt(r.get("share"), 3), r.get("note") or ""] for r in rows]


CHECK_HEAD = ["instrument/axis", "largest signal difference (of its peak)",
              "largest metric difference (relative)"]


def _cross_check(out_dir: Path, camp: dict):
    """The engine sentence and the cross-check rows (``verify.json``), if any."""
    engine = camp.get("engine", "cosim")
    if engine != "linear":
        return "Engine: co-simulation of every case.", [], []
    path = out_dir / "verify.json"
    rep = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}
    n = rep.get("n", 0)
    text = ("Engine: linear (the discretised models the FMUs step, closed once per "
            "configuration); " + (f"{n} case(s) with the largest jitter co-simulated "
                                  "as a cross-check, below." if n else
                                  "no case was cross-checked by co-simulation (--verify 0)."))
    rows = [[ia, f"{d['signal']:.2e}", f"{d['metric']:.2e}"]
            for ia, d in sorted(rep.get("largest_difference", {}).items())]
    flagged = [[c["case"], ", ".join(c["flags"])] for c in rep.get("nonlinear", [])]
    flagged += [[c["case"], "co-simulation failed: " + c["error"]]
                for c in rep.get("cases", []) if "error" in c]
    return text, rows, flagged


def _html_table(head, rows, cls=""):
    h = "".join(f"<th>{html.escape(c)}</th>" for c in head)
    body = []
    for row in rows:
        cells = []
        for c in row:
            style = ' class="fail"' if c == "FAIL" else (' class="pass"' if c == "pass" else "")
            cells.append(f"<td{style}>{html.escape(str(c))}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f'<table class="{cls}"><thead><tr>{h}</tr></thead><tbody>{"".join(body)}</tbody></table>'


def _md_table(head, rows):
    def esc(c):
        return str(c).replace("|", "\\|")

    lines = ["| " + " | ".join(esc(c) for c in head) + " |",
             "|" + "|".join("---" for _ in head) + "|"]
    lines += ["| " + " | ".join(esc(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


_CSS = """
body{font-family:sans-serif;max-width:1200px;margin:2em auto;color:#222}
table{border-collapse:collapse;font-size:12px;margin:1em 0}
th,td{border:1px solid #bbb;padding:3px 6px;text-align:right}
th{background:#eee} td:first-child,th:first-child{text-align:left}
td.fail{background:#f8d0d0;font-weight:bold} td.pass{background:#d6f0d6}
img{max-width:100%;border:1px solid #ddd;margin:0.5em 0}
"""


# ----------------------------------------------------------------------------- entry


def write_report(out_dir, fmt: str = "html", path=None) -> Path:
    """Write the report of a campaign output folder.

    Parameters
    ----------
    out_dir : path-like
        Campaign output folder (holds ``campaign.json`` and ``summary.parquet``).
    fmt : {"html", "md"}
        Self-contained HTML, or Markdown with PNG files in ``report_files/``.
    path : path-like, optional
        Report file (default ``out_dir/report.html`` or ``out_dir/report.md``).

    Returns
    -------
    Path
        The report file.
    """
    if fmt not in FORMATS:
        raise ReportError(f"report format {fmt!r} is unknown; expected one of {FORMATS}")
    out_dir = Path(out_dir)
    camp, summary, cases = _load(out_dir)
    unit = camp.get("unit", "arcsec")
    scale = ANGLE_UNITS.get(unit, 1.0)
    instruments = camp["instruments"]
    metric, window = _budget_metric(camp, summary)
    budget_rows = [r for r in summary if r["metric"] == metric
                   and _same_window(r["window"], window)]

    figures = []  # (section, title, Figure)
    if budget_rows:
        figures.append(("budget", "Jitter budget",
                        _budget_figure(budget_rows, instruments, unit, metric, window)))
    for inst, axes in instruments.items():
        event = _dominant(budget_rows, inst)
        if event is None:
            continue
        series = [s for s in _case_series(out_dir, camp, event, axes) if s[2]]
        if not series:
            continue
        figures.append(("history", f"{inst}: time history of {event}",
                        _history_figure(series, inst, event, unit, scale)))
        figures.append(("spectrum", f"{inst}: PSD and cumulative RMS, {event}",
                        spectrum_figure(series, inst, event, unit, scale,
                                        float(camp.get("skip", 0.0)))))
        if len(axes) >= 2:
            pair = _scatter_axes(axes)
            figures.append(("scatter", f"{inst}: boresight scatter, {event}",
                            _scatter_figure(series, inst, event, unit, scale, pair)))
    for p in _frf_files(out_dir):
        figures.append(("frf", f"Frequency response: {p.stem}", _frf_figure(p)))
    sweep_figs, worst = sweep_sections(out_dir, summary, instruments, metric, window, unit,
                                       RSS_EVENT)
    figures += [("sweep", t, f) for t, f in sweep_figs]
    unc_figs, unc_rows, unc_text = uncertainty_sections(out_dir, instruments, unit)
    figures += [("uncertainty", t, f) for t, f in unc_figs]

    failed = [[c["case"], c["error"]] for c in cases if c["status"] != "ok"]
    btab = _budget_rows(summary, metric, window)
    stab = _summary_rows(summary)
    n_ok = sum(c["status"] == "ok" for c in cases)
    title = f"Jitter report: {camp.get('name', out_dir.name)}"
    win = "" if window is None else f" over {window:g} s"
    intro = (f"{len(cases)} cases ({n_ok} finished, {len(failed)} failed). Values in {unit}; "
             f"budget metric: {metric}{win}. RSS = root-sum-square over the events of a "
             "configuration; change = (value − first configuration's) / first "
             "configuration's; requirements are the campaign file's inputs; margin = "
             "requirement − value; margin % = margin / requirement.")
    engine_text, check_rows, flagged = _cross_check(out_dir, camp)
    intro += " " + engine_text

    if fmt == "html":
        parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}"
                 f"</title><style>{_CSS}</style></head><body>",
                 f"<h1>{html.escape(title)}</h1><p>{html.escape(intro)}</p>",
                 "<h2>Budget</h2>", _html_table(BUDGET_HEAD, btab, "budget")]
        section = None
        names = {"budget": "Budget chart", "history": "Time histories of dominant cases",
                 "scatter": "Boresight image plane", "frf": "Frequency responses",
                 "sweep": "Sweeps: jitter against the swept quantity",
                 "spectrum": "Spectra of dominant cases",
                 "uncertainty": "Uncertainty: the budget as a distribution"}
        for sec, ftitle, fig in figures:
            if sec != section:
                parts.append(f"<h2>{names[sec]}</h2>")
                section = sec
            b64 = base64.b64encode(png_bytes(fig)).decode("ascii")
            parts.append(f"<figure><img alt='{html.escape(ftitle)}' "
                         f"src='data:image/png;base64,{b64}'><figcaption>"
                         f"{html.escape(ftitle)}</figcaption></figure>")
        if worst:
            parts += ["<h2>Worst points of the sweeps</h2>",
                      _html_table(WORST_HEAD, worst)]
        if unc_rows:
            parts += ["<h2>Budget at confidence levels</h2>",
                      f"<p>{html.escape(unc_text)}</p>", _html_table(UNC_HEAD, unc_rows)]
        if check_rows or flagged:
            parts += ["<h2>Cross-check of the linear engine</h2>",
                      _html_table(CHECK_HEAD, check_rows)]
        if flagged:
            parts += ["<p><b>Nonlinear in co-simulation</b> (the linear answer does not "
                      "hold for these cases):</p>", _html_table(["case", "flags"], flagged)]
        if failed:
            parts += ["<h2>Failed cases</h2>", _html_table(["case", "error"], failed)]
        parts += ["<h2>All results</h2>", _html_table(SUMMARY_HEAD, stab, "summary"),
                  "</body></html>"]
        target = Path(path) if path else out_dir / "report.html"
        target.write_text("\n".join(parts), encoding="utf-8")
        return target

    target = Path(path) if path else out_dir / "report.md"
    fig_dir = target.parent / "report_files"
    fig_dir.mkdir(parents=True, exist_ok=True)
    parts = [f"# {title}", "", intro, "", "## Budget", "", _md_table(BUDGET_HEAD, btab), ""]
    for i, (sec, ftitle, fig) in enumerate(figures):
        name = f"{i:02d}_{sec}_{slug(ftitle)[:40]}.png"
        (fig_dir / name).write_bytes(png_bytes(fig))
        parts += [f"### {ftitle}", "", f"![{ftitle}](report_files/{name})", ""]
    if worst:
        parts += ["## Worst points of the sweeps", "", _md_table(WORST_HEAD, worst), ""]
    if unc_rows:
        parts += ["## Budget at confidence levels", "", unc_text, "",
                  _md_table(UNC_HEAD, unc_rows), ""]
    if check_rows or flagged:
        parts += ["## Cross-check of the linear engine", "", _md_table(CHECK_HEAD, check_rows),
                  ""]
    if flagged:
        parts += ["**Nonlinear in co-simulation** (the linear answer does not hold for "
                  "these cases):", "", _md_table(["case", "flags"], flagged), ""]
    if failed:
        parts += ["## Failed cases", "", _md_table(["case", "error"], failed), ""]
    parts += ["## All results", "", _md_table(SUMMARY_HEAD, stab), ""]
    target.write_text("\n".join(parts), encoding="utf-8")
    return target
