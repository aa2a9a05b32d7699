"""Campaign reports: the verdict first, then the figures that explain it, then the tables.

:func:`write_report` reads a campaign output folder (see :mod:`orchestrator.campaign`) and
writes either one self-contained HTML file (figures embedded as base64 PNG) or a Markdown
file with PNG figures next to it.  Contents, in reading order:

1. The verdict (:mod:`orchestrator.report_verdict`), opened by a Monte Carlo line per
   configuration when the folder holds ``uncertainty.json`` (stable samples with the
   bound of the probability of instability, P(meet) and the 95/95 value of the weakest
   line; an unbounded value marked failing); then one row per instrument and axis, the
   RSS of every configuration side by side, the change, the requirement, margins,
   pass/fail and the dominant event.  The budget metric is the metric and window of the
   first requirement (or the first metric).
2. Budget chart (Fig. 8 style, :mod:`orchestrator.report_budget`): RSS bars of every
   configuration against the requirements; a heat map of every event x instrument-axis
   in the first configuration and one of each further configuration's change against it.
3. Time histories and spectra of the dominant event of each axis (the verdict's: one
   source, :attr:`~orchestrator.report_verdict.AxisVerdict.lead`), one figure per event
   with a panel per axis it dominates (of several instruments, the one nearest failing;
   the caption names every axis the event dominates, so no figure is drawn twice), every
   configuration overlaid in its own colour and line style, with the worst window of the
   budget metric and the requirement drawn (:mod:`orchestrator.report_figures`).
4. Boresight image plane (Fig. 16 style): roll against pitch when both exist, over each
   configuration's worst window with the requirement's box centred there; one per
   event, for the instrument nearest failing.
5. Frequency responses found in ``DIR/frf/*.parquet`` or ``*.csv`` (a ``frequency``
   column in Hz and magnitude columns, or complex ones as ``NAME.re``/``NAME.im``),
   sweeps and the uncertainty distribution when the campaign has them.
6. Folded below (HTML ``<details>``; Markdown: at the end): the budget per configuration
   (RSS rows with change, margin % and dominant event), worst sweep points, cross-check,
   failed cases, and every summary row.

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

import pyarrow.parquet as pq
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .campaign import ANGLE_UNITS, RSS_EVENT, slug
from .report_budget import BudgetGrid, _budget_figure, _group_label, _groups, budget_grid
from .report_figures import (
    Marking,
    Panel,
    ReportError,
    frf_figure,
    history_figure,
    scatter_axes,
    scatter_figure,
)
from .report_sweeps import (WORST_HEAD, spectrum_figure, sweep_sections, uncertainty_sections,
                            wheel_verdicts)
from .report_verdict import (fold_by_event, metric_words, montecarlo_lines, verdict_table,
                             verdicts, with_units)
from .report_verdict import same_window as _same_window

UNC_HEAD = ["configuration", "instrument", "axis", "metric", "P_c", "value",
            "bootstrap 95 %", "converged", "upper bound (assurance)", "requirement",
            "P(meet)", "P(meet) lower bound"]

__all__ = ["BudgetGrid", "ReportError", "budget_grid", "write_report"]

FORMATS = ("html", "md")


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


def png_bytes(fig: Figure) -> bytes:
    """A figure as PNG bytes (Agg canvas, 110 dpi)."""
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return buf.getvalue()


def _case_series(out_dir, camp, event, axes, cache):
    """(configuration label, time, {axis: values in rad}) for every case of an event."""
    out = []
    for c in camp["cases"]:
        if c["event"] != event:
            continue
        path = out_dir / "cases" / c["key"] / "results.parquet"
        if c["key"] not in cache:
            cache[c["key"]] = pq.read_table(path) if path.is_file() else None
        t = cache[c["key"]]
        if t is None:
            continue
        names = t.column_names
        tcol = "time" if "time" in names else names[0]
        cols = {a: t.column(v).to_numpy() for a, v in axes.items() if v in names}
        if cols:
            out.append((_group_label((c["configuration"], c["sweep"])) or event,
                        t.column(tcol).to_numpy(), cols))
    return out


def _frf_files(out_dir: Path):
    d = out_dir / "frf"
    if not d.is_dir():
        return []
    return sorted(p for p in d.iterdir() if p.suffix in (".parquet", ".csv"))


_ORDER = {"roll": 0, "pitch": 1, "yaw": 2}


def _share_note(v, configs) -> str:
    """A panel's note: the lead event's share of the RSS² in each configuration."""
    shares = " | ".join("–" if x != x else f"{100 * x:.0f} %" for x in v.lead_shares)
    return f"{v.lead} {shares} of the RSS²" + (f" ({' | '.join(configs)})"
                                                if len(configs) > 1 else "")


def _time_figures(out_dir, camp, configs, lines, metric, window, unit, scale):
    """The history and spectrum of each dominant event (a panel per axis it dominates,
    the instrument nearest failing drawn) and one boresight scatter per event."""
    figures, cache = [], {}
    skip = float(camp.get("skip", 0.0))
    marking = Marking(metric, window, {}, skip)
    for event, members in fold_by_event(lines).items():
        drawn: dict = {}
        for v in members:
            if v.axis not in drawn or v.severity > drawn[v.axis].severity:
                drawn[v.axis] = v
        panels = []
        for v in sorted(drawn.values(), key=lambda v: _ORDER.get(v.axis, 3)):
            var = camp["instruments"].get(v.instrument, {}).get(v.axis)
            series = [(label, t, cols[v.axis]) for label, t, cols in
                      _case_series(out_dir, camp, event, {v.axis: var}, cache)]
            if series:
                panels.append(Panel(v.instrument, v.axis, series, v.requirement,
                                    _share_note(v, configs)))
        if not panels:
            continue
        covered = ", ".join(f"{v.instrument} {v.axis}" for v in members)
        figures.append(("history", f"Time history of {event}, the dominant event of "
                        f"{covered}", history_figure(panels, event, unit, scale, marking)))
        figures.append(("spectrum", f"PSD and cumulative RMS of {event}, the dominant event "
                        f"of {covered}", spectrum_figure(panels, event, unit, scale, skip)))
    by_axis = {(v.instrument, v.axis): v for v in lines}
    groups: dict = {}
    for inst, axes in camp["instruments"].items():
        if len(axes) < 2:
            continue
        pair = scatter_axes(axes)
        mine = [by_axis[(inst, a)] for a in pair if (inst, a) in by_axis]
        if not mine or all(v.lead is None for v in mine):
            continue
        worst = max((v for v in mine if v.lead), key=lambda v: v.severity)
        groups.setdefault((worst.lead, pair), []).append((max(v.severity for v in mine),
                                                          inst))
    for (event, pair), members in groups.items():
        members.sort(key=lambda m: -m[0])
        inst = members[0][1]
        axes = camp["instruments"][inst]
        series = _case_series(out_dir, camp, event, {a: axes[a] for a in pair}, cache)
        if not series:
            continue
        reqs = {a: by_axis[(inst, a)].requirement for a in pair if (inst, a) in by_axis}
        others = [m[1] for m in members[1:]]
        also = f" (also the lead of {', '.join(others)}: not drawn again)" if others else ""
        where = (f" over the worst {window:g} s window" if marking.windowed else "")
        figures.append(("scatter", f"{inst}: boresight {pair[0]}–{pair[1]}{where}, "
                        f"{event}{also}",
                        scatter_figure(series, inst, event, unit, scale, pair,
                                       Marking(metric, window, reqs, skip))))
    order = ("history", "spectrum", "scatter")
    return sorted(figures, key=lambda f: order.index(f[0]))   # stable: event order


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
            style = {"FAIL": ' class="fail"', "pass": ' class="pass"',
                     "incomplete": ' class="incomplete"'}.get(c, "")
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
td.fail,span.fail{background:#f8d0d0;font-weight:bold} td.pass{background:#d6f0d6}
td.incomplete{background:#f6ecc8} table.text td{text-align:left}
table.verdict td:nth-child(2),table.verdict td:last-child{text-align:left}
img{max-width:100%;border:1px solid #ddd;margin:0.5em 0}
h1{font-size:22px;margin:0.3em 0} h2{font-size:17px;margin:1.2em 0 0.4em}
p,ul.mc{font-size:13px;margin:0.4em 0} p.key{font-size:11px;color:#555}
details{margin:0.6em 0;font-size:13px} summary{cursor:pointer}
"""


# ----------------------------------------------------------------------------- entry


_SECTIONS = {"budget": "Budget chart",
             "history": "Time histories: the dominant event of each axis",
             "spectrum": "Spectra of the dominant events",
             "scatter": "Boresight image plane", "frf": "Frequency responses",
             "sweep": "Sweeps: jitter against the swept quantity",
             "uncertainty": "Uncertainty: the budget as a distribution"}


def _contents(out_dir: Path):
    """Everything the report shows, format-free: texts, tables and figures."""
    camp, summary, cases = _load(out_dir)
    unit = camp.get("unit", "arcsec")
    scale = ANGLE_UNITS.get(unit, 1.0)
    instruments = camp["instruments"]
    metric, window = _budget_metric(camp, summary)
    budget_rows = [r for r in summary if r["metric"] == metric
                   and _same_window(r["window"], window)]
    configs, lines = verdicts(summary, metric, window)

    figures = []  # (section, title, Figure)
    if budget_rows:
        figures.append(("budget", "Jitter budget",
                        _budget_figure(budget_rows, instruments, unit, metric, window)))
    figures += _time_figures(out_dir, camp, configs, lines, metric, window, unit, scale)
    for p in _frf_files(out_dir):
        figures.append(("frf", f"Frequency response: {p.stem}", frf_figure(p)))
    sweep_figs, worst = sweep_sections(out_dir, summary, instruments, metric, window, unit,
                                       RSS_EVENT, camp.get("sweep_units"))
    figures += [("sweep", t, f) for t, f in sweep_figs]
    unc_figs, unc_rows, unc_text = uncertainty_sections(out_dir, instruments, unit)
    figures += [("uncertainty", t, f) for t, f in unc_figs]

    failed = [[c["case"], c["error"]] for c in cases if c["status"] != "ok"]
    n_ok = sum(c["status"] == "ok" for c in cases)
    swept = any(v for line in lines for v in line.sweep)
    engine_text, check_rows, flagged = _cross_check(out_dir, camp)
    wheel = not lines
    if wheel:   # a campaign of wheel sweeps alone: their worst speeds are the verdict
        configs, lines = wheel_verdicts(out_dir, metric, window)
    vhead, vrows = verdict_table(configs, with_units(lines, camp.get("sweep_units") or {}),
                                 "worst" if wheel else "RSS")
    n_fail = sum(row.count("FAIL") > 0 for row in vrows)
    unc_path = out_dir / "uncertainty.json"
    mc = (montecarlo_lines(json.loads(unc_path.read_text(encoding="utf-8")), metric, window)
          if unc_path.is_file() else [])
    return {
        "title": f"Jitter report: {camp.get('name', out_dir.name)}",
        "intro": ((f"{metric_words(metric, window)} in {unit}, steady state over the "
                   "wheel sweeps: each configuration's worst speed; "
                   if wheel and lines else
                   f"{metric_words(metric, window)} in {unit}, RSS over the events; "
                   f"{len(cases)} cases ({n_ok} finished, {len(failed)} failed); ")
                  + f"{len(vrows)} instrument axes, "
                  f"{n_fail} failing in at least one configuration."
                  + (" With sweeps, each configuration's worst sweep point." if swept
                     and not wheel else "")),
        "verdict": (vhead, vrows), "mc": mc,
        "empty": ("" if vrows else "No verdict: the campaign finished no case, and has no "
                  "wheel sweep, with the budget metric; see the failed cases below."),
        "key": ("RSS = root-sum-square over the events of a configuration; change = (last "
                "configuration − first) / first; requirements are the campaign file's "
                "inputs; margin = requirement − RSS; dominant event: the largest share of "
                "the RSS² (value² / RSS²) in the configuration of largest RSS, the event "
                "the figures follow, with its share in every configuration. "
                + engine_text),
        "figures": figures, "worst": worst, "unc": (unc_rows, unc_text),
        "check": (check_rows, flagged), "failed": failed,
        "budget": _budget_rows(summary, metric, window), "summary": _summary_rows(summary),
    }


def _folded_html(title, table, n):
    return (f"<details><summary><b>{html.escape(title)}</b> ({n} rows)</summary>{table}"
            "</details>")


def _html(c) -> str:
    vhead, vrows = c["verdict"]
    parts = [(f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>"
              f"{html.escape(c['title'])}</title><style>{_CSS}</style></head><body>"),
             f"<h1>{html.escape(c['title'])}</h1>",
             "<h2 id='verdict'>Verdict</h2>"]
    if c["mc"]:
        parts.append("<ul class='mc'>" + "".join(
            "<li>" + "".join(f"<span class='{cls}'>{html.escape(t)}</span>" if cls
                             else html.escape(t) for t, cls in pieces) + "</li>"
            for pieces in c["mc"]) + "</ul>")
    parts += [f"<p>{html.escape(c['empty'] or c['intro'])}</p>",
              _html_table(vhead, vrows, "verdict"),
              f"<p class='key'>{html.escape(c['key'])}</p>"]
    if c["failed"]:
        parts += ["<h2>Failed cases</h2>",
                  _html_table(["case", "error"], c["failed"], "text")]
    section = None
    for sec, ftitle, fig in c["figures"]:
        if sec != section:
            parts.append(f"<h2>{_SECTIONS[sec]}</h2>")
            section = sec
        b64 = base64.b64encode(png_bytes(fig)).decode("ascii")
        parts.append(f"<figure><img alt='{html.escape(ftitle)}' "
                     f"src='data:image/png;base64,{b64}'><figcaption>"
                     f"{html.escape(ftitle)}</figcaption></figure>")
    unc_rows, unc_text = c["unc"]
    if unc_rows:
        parts += ["<h2>Budget at confidence levels</h2>", f"<p>{html.escape(unc_text)}</p>",
                  _html_table(UNC_HEAD, unc_rows)]
    check_rows, flagged = c["check"]
    if check_rows or flagged:
        parts += ["<h2>Cross-check of the linear engine</h2>",
                  _html_table(CHECK_HEAD, check_rows)]
    if flagged:
        parts += [("<p><b>Nonlinear in co-simulation</b> (the linear answer does not "
                   "hold for these cases):</p>"), _html_table(["case", "flags"], flagged)]
    parts.append("<h2>Tables</h2>")
    parts.append(_folded_html("Budget by configuration",
                              _html_table(BUDGET_HEAD, c["budget"], "budget"),
                              len(c["budget"])))
    if c["worst"]:
        parts.append(_folded_html("Worst points of the sweeps",
                                  _html_table(WORST_HEAD, c["worst"]), len(c["worst"])))
    parts.append(_folded_html("All results", _html_table(SUMMARY_HEAD, c["summary"],
                                                         "summary"), len(c["summary"])))
    parts.append("</body></html>")
    return "\n".join(parts)


def _markdown(c, fig_dir: Path) -> str:
    vhead, vrows = c["verdict"]
    parts = [f"# {c['title']}", "", "## Verdict", ""]
    if c["mc"]:   # a failing piece in bold
        parts += ["- " + "".join(f"**{t}**" if cls else t for t, cls in pieces)
                  for pieces in c["mc"]] + [""]
    parts += [c["empty"] or c["intro"], "",
             _md_table(vhead, vrows), "", c["key"], ""]
    if c["failed"]:
        parts += ["## Failed cases", "", _md_table(["case", "error"], c["failed"]), ""]
    section = None
    for i, (sec, ftitle, fig) in enumerate(c["figures"]):
        if sec != section:
            parts += [f"## {_SECTIONS[sec]}", ""]
            section = sec
        name = f"{i:02d}_{sec}_{slug(ftitle)[:40]}.png"
        (fig_dir / name).write_bytes(png_bytes(fig))
        parts += [f"### {ftitle}", "", f"![{ftitle}]({fig_dir.name}/{name})", ""]
    unc_rows, unc_text = c["unc"]
    if unc_rows:
        parts += ["## Budget at confidence levels", "", unc_text, "",
                  _md_table(UNC_HEAD, unc_rows), ""]
    check_rows, flagged = c["check"]
    if check_rows or flagged:
        parts += ["## Cross-check of the linear engine", "", _md_table(CHECK_HEAD, check_rows),
                  ""]
    if flagged:
        parts += [("**Nonlinear in co-simulation** (the linear answer does not hold for "
                   "these cases):"), "", _md_table(["case", "flags"], flagged), ""]
    parts += ["## Budget by configuration", "", _md_table(BUDGET_HEAD, c["budget"]), ""]
    if c["worst"]:
        parts += ["## Worst points of the sweeps", "", _md_table(WORST_HEAD, c["worst"]), ""]
    parts += ["## All results", "", _md_table(SUMMARY_HEAD, c["summary"]), ""]
    return "\n".join(parts)


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
    contents = _contents(out_dir)
    if fmt == "html":
        target = Path(path) if path else out_dir / "report.html"
        target.write_text(_html(contents), encoding="utf-8")
        return target
    target = Path(path) if path else out_dir / "report.md"
    fig_dir = target.parent / "report_files"
    fig_dir.mkdir(parents=True, exist_ok=True)
    target.write_text(_markdown(contents, fig_dir), encoding="utf-8")
    return target
