"""The verdict that opens a campaign report: one row per instrument and axis.

:func:`verdicts` reads the RSS rows of the budget metric and gives, per instrument and
axis, the RSS of every configuration side by side (with sweeps: its worst point), the
requirement, the margins, pass or fail and the dominant event.  An axis's dominant event
has one source, :attr:`AxisVerdict.lead`: the event with the largest share of the RSS² in
the configuration of largest RSS (the one nearest failing).  The table names it first and
the report's figures follow it (:func:`fold_by_event`).
:func:`montecarlo_lines` opens the verdict of a campaign with a Monte Carlo: per
configuration, its stability and its weakest line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from .campaign import RSS_EVENT

__all__ = [
    "AxisVerdict",
    "fold_by_event",
    "metric_words",
    "montecarlo_lines",
    "verdict_table",
    "verdicts",
    "with_units",
]

_WORDS = {"peak_to_peak": "peak-to-peak", "rms_jitter": "RMS jitter",
          "stability": "stability (RMS change)", "rms": "RMS", "ape": "APE", "mpe": "MPE",
          "rpe": "RPE", "pde": "PDE"}


def metric_words(kind, window=None) -> str:
    """A metric kind as a report says it: ``peak_to_peak``, 1.8 -> "peak-to-peak over
    1.8 s" (a stability's window is its lag).

    Parameters
    ----------
    kind : str or None
        Metric kind (``"peak_to_peak"``, ``"rms_jitter"``, ``"stability"``, ``"rms"``,
        ``"ape"``, ...); an unknown kind is said as it is, None as "".
    window : float, optional
        The metric's window (s; a stability's lag); None: no window in the words.
    """
    words = _WORDS.get(kind, kind or "")
    if window is None:
        return words
    return f"{words} {'across' if kind == 'stability' else 'over'} {float(window):g} s"


def same_window(a, b) -> bool:
    """Whether two metric windows are the same (equal to ``math.isclose``; None only
    equals None).

    Parameters
    ----------
    a, b : float or None
        The windows (s), None for a metric without one.
    """
    if a is None or b is None:
        return a is None and b is None
    return math.isclose(float(a), float(b))


def _finite(v) -> bool:
    return v is not None and not math.isnan(v)


@dataclass(frozen=True)
class AxisVerdict:
    """The budget of one instrument axis in every configuration.

    Parameters
    ----------
    instrument, axis : str
        The line of sight.
    rss : tuple of float
        RSS over the events per configuration (report unit; NaN where missing); with
        sweeps, the largest over the configuration's sweep points.
    sweep : tuple of str
        Sweep point of each configuration's RSS ("" without sweeps).
    requirement : float
        Requirement (report unit; NaN without one).
    passed : tuple of bool, None or "incomplete"
        RSS within the requirement, per configuration (None: no requirement;
        "incomplete": an RSS missing failed events and still within the requirement;
        one already above it fails).
    dominant : tuple of (str, float) or None
        Event with the largest share of the RSS² and that share, per configuration.
    lead : str or None
        The axis's dominant event: that of the configuration of largest RSS.
    lead_shares : tuple of float
        The lead event's share of the RSS² in each configuration (NaN where missing).
    """

    instrument: str
    axis: str
    rss: tuple
    sweep: tuple
    requirement: float
    passed: tuple
    dominant: tuple
    lead: str | None = None
    lead_shares: tuple = ()

    @property
    def severity(self) -> float:
        """Largest RSS over the configurations, relative to the requirement when there
        is one (-inf without any finite RSS)."""
        worst = max((v for v in self.rss if _finite(v)), default=-math.inf)
        req = self.requirement
        return worst / req if _finite(req) and req > 0 and math.isfinite(worst) else worst

    @property
    def margin(self) -> tuple:
        """Requirement − RSS per configuration (report unit; NaN without requirement)."""
        return tuple(self.requirement - v if _finite(self.requirement) else math.nan
                     for v in self.rss)


def _budget(rows, metric, window):
    return [r for r in rows if r["metric"] == metric and same_window(r["window"], window)]


def verdicts(rows, metric, window):
    """Configurations and one :class:`AxisVerdict` per instrument and axis.

    Parameters
    ----------
    rows : list of dict
        Summary rows (:data:`orchestrator.campaign.summary.SUMMARY_SCHEMA`).
    metric : str
        Budget metric kind.
    window : float or None
        Its window (s).

    Returns
    -------
    configurations : list of str
        In campaign order ("" for a campaign without configurations).
    lines : list of AxisVerdict
        Instruments and axes in campaign order.
    """
    rows = _budget(rows, metric, window)
    rss = [r for r in rows if r["event"] == RSS_EVENT]
    configs = list(dict.fromkeys(r["configuration"] for r in rss))
    lines = list(dict.fromkeys((r["instrument"], r["axis"]) for r in rss))
    events: dict = {}
    for r in rows:
        if r["event"] != RSS_EVENT:
            key = (r["instrument"], r["axis"], r["configuration"], r["sweep"])
            events.setdefault(key, []).append(r)
    out = []
    for inst, axis in lines:
        vals, sweeps, passed, dom, req, shares = [], [], [], [], math.nan, []
        for cf in configs:
            mine = [r for r in rss if (r["instrument"], r["axis"], r["configuration"])
                    == (inst, axis, cf)]
            worst = max(mine, key=lambda r: r["value"] if _finite(r["value"]) else -math.inf,
                        default=None)
            if worst is None:
                vals.append(math.nan), sweeps.append(""), passed.append(None)
                dom.append(None), shares.append({})
                continue
            vals.append(worst["value"] if _finite(worst["value"]) else math.nan)
            sweeps.append(worst["sweep"] or "")
            if _finite(worst["requirement"]):
                req = worst["requirement"]
            ok = worst["pass"]
            if ok is None and worst.get("note") and _finite(req) and vals[-1] > req:
                ok = False   # failed events only add to an RSS already above it
            passed.append("incomplete" if ok is None and worst.get("note") else ok)
            contrib = events.get((inst, axis, cf, worst["sweep"]), [])
            top = max(contrib, key=lambda r: r.get("share") or 0.0, default=None)
            dom.append(None if top is None else (top["event"], top.get("share") or 0.0))
            shares.append({r["event"]: r.get("share") or 0.0 for r in contrib})
        known = [k for k, d in enumerate(dom) if d is not None]
        lead = None
        if known:   # the configuration of largest RSS decides (NaN ranks last)
            k = max(known, key=lambda k: vals[k] if _finite(vals[k]) else -math.inf)
            lead = dom[k][0]
        out.append(AxisVerdict(inst, axis, tuple(vals), tuple(sweeps), req, tuple(passed),
                               tuple(dom), lead,
                               tuple(sh.get(lead, math.nan) for sh in shares)))
    return configs, out


def _num(v, digits=4):
    return "" if not _finite(v) else f"{v:.{digits}g}"


def _dominant_text(v: AxisVerdict, configs) -> str:
    """The lead event first with its share in every configuration, then any
    configuration that another event leads."""
    if v.lead is None:
        return ""
    shares = " | ".join("–" if not _finite(x) else f"{100 * x:.0f} %" for x in v.lead_shares)
    others = [f"{d[0]} leads {cf or 'all cases'} ({100 * d[1]:.0f} %)"
              for cf, d in zip(configs, v.dominant) if d is not None and d[0] != v.lead]
    return f"{v.lead} ({shares})" + "".join(f"; {o}" for o in others)


def verdict_table(configs, lines, value_name: str = "RSS"):
    """Header and rows of the verdict table (strings; pass cells "pass" or "FAIL").

    Columns: instrument, axis, the RSS of every configuration, the change of the last
    configuration against the first (with two or more), requirement, the margin and the
    verdict of every configuration, with sweeps where each configuration's value is worst
    ("worst at"), and the dominant event (:attr:`AxisVerdict.lead`) with its share of
    the RSS² in each configuration, then any configuration another event leads.

    Parameters
    ----------
    configs : list of str
        Configuration names (:func:`verdicts`).
    lines : list of AxisVerdict
    value_name : str
        What the values are, in the header (``"RSS"``; a wheel sweep's ``"worst"``).

    Returns
    -------
    head : list of str
    rows : list of list of str
    """
    names = [c or "all cases" for c in configs]
    many = len(configs) > 1
    head = (["instrument", "axis"] + [f"{value_name} {n}" for n in names]
            + (["change"] if many else []) + ["requirement"]
            + [f"margin {n}" for n in names] + [f"verdict {n}" for n in names]
            + (["worst at" + (" (per configuration)" if many else "")]
               if any(v.sweep for v in lines) else [])
            + ["dominant event (share" + (" per configuration)" if many else ")")])
    rows = []
    for v in lines:
        row = [v.instrument, v.axis] + [_num(x) for x in v.rss]
        if many:
            a, b = v.rss[0], v.rss[-1]
            row.append(f"{100 * (b - a) / a:+.1f} %" if _finite(a) and _finite(b) and a > 0
                       else "")
        row.append(_num(v.requirement))
        row += [_num(m) for m in v.margin]
        row += [{None: "", "incomplete": "incomplete", True: "pass", False: "FAIL"}[p]
                for p in v.passed]
        if any(v.sweep for v in lines):
            row.append(" | ".join(v.sweep))
        row.append(_dominant_text(v, configs))
        rows.append(row)
    return head, rows


def with_units(lines, units: dict) -> list:
    """The verdict lines with each sweep point in its parameter's unit.

    Parameters
    ----------
    lines : list of AxisVerdict
        From :func:`verdicts`; their ``sweep`` points read ``"p=v"`` (``", "`` between
        several parameters).
    units : dict of str to str
        Unit of each swept parameter (``campaign.json``'s ``sweep_units``).

    Returns
    -------
    list of AxisVerdict
        ``"excitation.freq1=8.4 Hz"`` where ``units`` knows the parameter.
    """
    def text(point):
        return ", ".join(f"{p} {units[p.partition('=')[0]]}" if units.get(p.partition("=")[0])
                         else p for p in point.split(", ")) if point else point
    return [replace(v, sweep=tuple(text(pt) for pt in v.sweep)) for v in lines]


def fold_by_event(lines) -> dict:
    """The instrument axes grouped by their dominant event (:attr:`AxisVerdict.lead`).

    Parameters
    ----------
    lines : list of AxisVerdict

    Returns
    -------
    dict
        ``{event: [AxisVerdict]}``, events in the order of their first axis, axes
        without a dominant event left out.
    """
    out: dict = {}
    for v in lines:
        if v.lead is not None:
            out.setdefault(v.lead, []).append(v)
    return out


def _weakest(lines, metric, window):
    """The line of a configuration that least meets its requirement: the lowest P(meet),
    then the largest upper bound against the requirement (without requirements, the
    largest bound); the budget metric's lines when there are some."""
    mine = [ln for ln in lines if ln["metric"] == metric
            and same_window(ln.get("window"), window)] or lines

    def bound(ln):
        q = next(iter(ln.get("quantiles", {}).values()), {})
        b = q.get("upper_bound", q.get("value", math.nan))
        req = ln.get("requirement")
        return b / req if _finite(req) and req > 0 else b

    return min(mine, key=lambda ln: (ln.get("p_meet", 1.0),
                                     -bound(ln) if _finite(bound(ln)) else -math.inf))


def montecarlo_lines(report, metric, window):
    """The Monte Carlo lines that open a verdict, one per configuration.

    Each says how many samples are stable with the one-sided upper bound of the
    probability of instability, and for the configuration's weakest line (lowest
    P(meet)) P(meet) with its lower bound and the value at P_c = 0.95 (else the first
    level) with its upper bound at the run's assurance (the 95/95 value).  An infinite
    value reads "unbounded: N of M samples unstable", marked failing, with the inputs
    most related to the instability.

    Parameters
    ----------
    report : dict
        The content of ``uncertainty.json``.
    metric : str
        The budget metric kind.
    window : float or None
        Its window (s).

    Returns
    -------
    list of list of (str, str)
        Per configuration, its text as pieces with a class: "" or ``"fail"``.
    """
    from .campaign.mcresults import unstable_upper_bound

    n, assurance = report["samples"], report.get("assurance", 0.95)
    at = f"{100 * assurance:g} %"
    out = []
    for cf, k in report.get("unstable", {}).items():
        lines = [ln for ln in report.get("lines", []) if ln["configuration"] == cf]
        bound = (report.get("stability") or {}).get(cf, {}).get(
            "unstable_upper_bound", unstable_upper_bound(k, n, assurance))
        parts = [(f"Monte Carlo, {cf or 'all cases'}: ", ""),
                 (f"{n - k} of {n} samples stable", "fail" if k else ""),
                 (f" (probability of instability <= {bound:.3g} at {at})", "")]
        if lines:
            ln = _weakest(lines, metric, window)
            qs = ln.get("quantiles", {})
            pc = next((p for p in qs if float(p) == 0.95), next(iter(qs), None))
            parts.append((f"; weakest line {ln['instrument']} {ln['axis']}, "
                          f"{metric_words(ln['metric'], ln.get('window'))}", ""))
            if "p_meet" in ln:
                low = (f" (>= {ln['p_meet_low']:.3f} at {at})" if "p_meet_low" in ln
                       else "")
                parts.append((f": P(meet {ln['requirement']:g} {ln['unit']}) = "
                              f"{ln['p_meet']:.3f}{low}", ""))
            if pc is not None:
                parts += _bound_pieces(qs[pc], ln, float(pc), assurance, report, cf)
        out.append(parts)
    return out


def _bound_pieces(q, line, pc, assurance, report, cf):
    """The P_c/assurance value of a line as pieces: the bound, the count it needs, or
    an unbounded value with the inputs most related to the instability."""
    from .campaign.mcresults import unbounded_words

    label = f", {100 * pc:g}/{100 * assurance:g} value "
    if math.isfinite(q.get("value", math.nan)) and q.get("upper_rank") is None:
        return [(label + f"needs {q.get('samples_for_bound')} samples", "")]
    b = q.get("upper_bound", q.get("value", math.nan))
    if _finite(b) and math.isfinite(b):
        return [(label + f"{b:.4g} {line['unit']}", "")]
    key = "unstable" if line.get("unstable") else "limit_reached"
    drivers = ((report.get("drivers") or {}).get(key) or {}).get(cf) or {}
    top = sorted(drivers, key=lambda name: (-abs(drivers[name]), name))[:3]
    named = ", ".join(f"{d} {drivers[d]:+.2f}" for d in top)
    return [(label, ""), (unbounded_words(line), "fail"),
            (f" (drivers, rank correlation with the flag: {named})" if top else "", "")]
