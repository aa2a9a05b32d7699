"""The campaign's summary: jitter per case, RSS over the events, margins to requirements."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pyarrow as pa

from .. import metrics as M
from ..results import column_array, read_parquet, rows_table
from .cases import Campaign
from .spec import ANGLE_UNITS, RSS_EVENT
from .store import METRICS_FILE, case_status, write_table

#: The RSS rows of the summary, as CSV.
BUDGET_CSV = "budget.csv"
SUMMARY_SCHEMA = pa.schema([
    ("case", pa.string()), ("key", pa.string()), ("event", pa.string()),
    ("configuration", pa.string()), ("sweep", pa.string()), ("instrument", pa.string()),
    ("axis", pa.string()), ("metric", pa.string()), ("window", pa.float64()),
    ("unit", pa.string()), ("value", pa.float64()), ("requirement", pa.float64()),
    ("margin", pa.float64()), ("margin_ratio", pa.float64()), ("pass", pa.bool_()),
    ("share", pa.float64()), ("note", pa.string()), ("cross_check", pa.string()),
])
# Columns of cases.parquet.
_CASES_SCHEMA = pa.schema([
    ("key", pa.string()), ("case", pa.string()), ("event", pa.string()),
    ("configuration", pa.string()), ("sweep", pa.string()), ("status", pa.string()),
    ("error", pa.string()), ("seconds", pa.float64()),
])


def summarize(campaign: Campaign, out_dir) -> tuple[pa.Table, pa.Table]:
    """Build the summary and case tables from the case folders.

    Summary rows: one per successful case × instrument × axis × metric × window, plus
    one ``event = "RSS"`` row per configuration × sweep point × instrument × axis ×
    metric × window holding the root-sum-square over the events.  Values, requirements
    and margins are in ``campaign.unit``; ``margin = requirement − value``,
    ``margin_ratio = margin / requirement``, ``pass = value <= requirement`` (null without
    a requirement or for an RSS missing failed events, see ``note``); ``share`` is an
    event's fraction ``value² / RSS²`` of its group's RSS; ``cross_check`` says, for a
    case of the linear engine co-simulated by ``--verify`` (``verify.json``), how far
    the two engines differ and whether a rail or limit was active in the co-simulation.

    Parameters
    ----------
    campaign : Campaign
        With its final keys (:func:`~orchestrator.campaign.keyed`).
    out_dir : path-like
        Campaign folder (holds ``cases/KEY``).

    Returns
    -------
    summary : pyarrow.Table
        Columns of :data:`SUMMARY_SCHEMA`.
    cases : pyarrow.Table
        One row per case: key, case, event, configuration, sweep, status, error, seconds.
    """
    cases_dir = Path(out_dir) / "cases"
    checks = _cross_checks(Path(out_dir))
    scale = ANGLE_UNITS[campaign.unit]
    rows, case_rows = [], []
    groups: dict = {}
    failed_groups: dict = {}
    for case in campaign.cases:
        st = case_status(cases_dir, case.key) or {"status": "missing", "error": "not run"}
        case_rows.append({"key": case.key, "case": case.label, "event": case.event,
                          "configuration": case.configuration, "sweep": case.sweep,
                          "status": st["status"], "error": st.get("error", ""),
                          "seconds": st.get("seconds")})
        gk = (case.configuration, case.sweep)
        if st["status"] != "ok":
            failed_groups.setdefault(gk, []).append(case.event)
            continue
        mt = read_parquet(cases_dir / case.key / METRICS_FILE).to_pylist()
        for r in mt:
            v = r["value"] * scale
            rows.append({"case": case.label, "key": case.key, "event": case.event,
                         "configuration": case.configuration, "sweep": case.sweep,
                         "instrument": r["instrument"], "axis": r["axis"],
                         "metric": r["metric"], "window": r["window"], "value": v})
            line = (r["instrument"], r["axis"], r["metric"], r["window"])
            groups.setdefault(gk, {}).setdefault(line, []).append(len(rows) - 1)
    for (cf, sw), lines in groups.items():
        missing = failed_groups.get((cf, sw), [])
        for (inst, axis, metric, window), idx in lines.items():
            total = float(M.rss([rows[i]["value"] for i in idx]))
            for i in idx:
                rows[i]["share"] = rows[i]["value"] ** 2 / total**2 if total > 0 else 0.0
            label = " | ".join(x for x in (RSS_EVENT, cf, sw) if x)
            rows.append({"case": label, "key": "", "event": RSS_EVENT, "configuration": cf,
                         "sweep": sw, "instrument": inst, "axis": axis, "metric": metric,
                         "window": window, "value": total, "share": 1.0,
                         "note": f"incomplete: failed event(s) {missing}" if missing else ""})
    for r in rows:
        req = campaign.requirement(r["instrument"], r["axis"], r["metric"], r["window"])
        r["unit"] = campaign.unit
        r["requirement"] = req
        r.setdefault("note", "")
        r["cross_check"] = checks.get((r["key"], r["instrument"], r["axis"]), "")
        if math.isnan(req):
            r["margin"] = r["margin_ratio"] = math.nan
            r["pass"] = None
        else:
            a, ratio = M.margin(r["value"], req)
            r["margin"], r["margin_ratio"] = float(a), float(ratio)
            r["pass"] = None if r["note"] else bool(r["value"] <= req)
    summary = rows_table(rows, SUMMARY_SCHEMA)
    for name, values in _sweep_columns([r["sweep"] for r in rows]).items():
        summary = summary.append_column(pa.field(name, pa.float64()),
                                        column_array(np.asarray(values, float)))
    cases = rows_table(case_rows, _CASES_SCHEMA)
    return summary, cases


def _sweep_columns(sweeps: list) -> dict:
    """One numeric column per swept parameter, from the ``sweep`` labels ``p=v, q=w``
    (NaN where a row has no such point, or a value that is not a number)."""
    points = []
    for label in sweeps:
        point = {}
        for part in filter(None, (label or "").split(", ")):
            name, _, value = part.partition("=")
            try:
                point[name] = float(value)
            except ValueError:
                point[name] = math.nan
        points.append(point)
    names = list(dict.fromkeys(n for p in points for n in p))
    return {n: [p.get(n, math.nan) for p in points] for n in names}


def _cross_checks(out: Path) -> dict:
    """``(key, instrument, axis) -> words`` from ``verify.json`` (linear engine), if any."""
    path = out / "verify.json"
    if not path.is_file():
        return {}
    try:
        rep = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    words = {}
    for case in rep.get("cases", []):
        flags = case.get("nonlinear_flags") or []
        for ia, d in (case.get("axes") or {}).items():
            inst, _, axis = ia.partition("/")
            text = (f"co-simulated: metric differs by {d['metric']:.1e}, signal by "
                    f"{d['signal']:.1e} of its peak")
            if flags:
                text = f"NONLINEAR in co-simulation ({', '.join(flags)}); " + text
            words[(case["key"], inst, axis)] = text
    return words


def write_summary(campaign: Campaign, out_dir) -> Path:
    """Write summary.parquet, summary.csv, budget.csv and cases.parquet/.csv atomically.

    ``summary.parquet`` holds every row; for spreadsheet readers ``summary.csv`` holds
    the case rows and ``budget.csv`` the RSS rows (the budget against the requirements).
    A swept parameter is a numeric column of its own in all three.

    Parameters
    ----------
    campaign : Campaign
        With its final keys.
    out_dir : path-like
        Campaign folder.

    Returns
    -------
    Path
        ``out_dir/summary.parquet``.
    """
    out = Path(out_dir)
    summary, cases = summarize(campaign, out)
    write_table(summary, out / "summary.parquet")
    # rows picked by index: comparing with a Python string converts it, which imports
    # pandas (0.17 s)
    is_rss = np.array([e == RSS_EVENT for e in summary.column("event").to_pylist()], bool)
    write_table(summary.take(column_array(np.flatnonzero(~is_rss))), out / "summary.csv",
                csv=True)
    write_table(summary.take(column_array(np.flatnonzero(is_rss))), out / BUDGET_CSV,
                csv=True)
    write_table(cases, out / "cases.parquet")
    write_table(cases, out / "cases.csv", csv=True)
    return out / "summary.parquet"
