"""What a Monte Carlo's samples give (:mod:`orchestrator.campaign.montecarlo`): the
statistics of every line, whether they converged, the inputs related to each status,
the per-sample table, the content of ``uncertainty.json`` and the command's lines.

A sample whose closed loop is unstable in a configuration (status ``UNSTABLE``) counts
as exceeding every requirement there: its value is ``inf`` in every line of that
configuration, as a sample whose record reached a rail or limit (``LIMIT``), so that
``p_meet``, ``meets``, ``meets_assured`` and ``p_meet_low`` count it as failing however
small its record stayed (a loop that grows keeps growing past any record).  The record
as computed stays in the per-sample table (``record_value``), and ``uncertainty.json``
counts the unstable samples of each configuration with the one-sided Clopper-Pearson
upper bound of the probability of instability (``stability``)."""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
import pyarrow as pa

from .spec import ANGLE_UNITS

SAMPLES_FILE = "uncertainty_samples.parquet"
UNCERTAINTY_FILE = "uncertainty.json"
# the status bits of a sample and configuration (uncertainty.json counts each)
LIMIT, UNSTABLE, DIVERGING = 1, 2, 4
# how the linear engine took it: on the dense loop (not the structured one), its poles
# decided by dense eigenvalues (not counted from the structure); counted per
# configuration in uncertainty.json's linear_engine
DENSE_LOOP, POLES_BY_EIGENVALUES = 8, 16
_STATUS = {"unstable": UNSTABLE, "diverging_in_record": DIVERGING, "limit_reached": LIMIT}


def _budgets(campaign, ctx, values):
    """``(configuration, instrument, axis, metric, window, x)`` of every line, ``x`` the
    RSS over the events of each sample in the campaign's unit (inf: out of the model;
    NaN: not evaluated)."""
    rss = np.sqrt(np.sum(values**2, axis=2))                   # (n, configs, pairs, m)
    scale = ANGLE_UNITS[campaign.unit]
    for ci, cf in enumerate(ctx["configs"]):
        for j, (inst, axis, _) in enumerate(ctx["pairs"]):
            for k, (kind, window) in enumerate(campaign.metrics):
                yield ci, cf, inst, axis, kind, window, rss[:, ci, j, k] * scale


def _counted(values, status) -> np.ndarray:
    """``values`` with every metric of an unstable sample and configuration ``inf``: it
    exceeds every requirement whatever its record (module docstring)."""
    out = np.array(values, float)
    out[(status & UNSTABLE) > 0] = np.inf
    return out


def _samples_table(campaign, ctx, values, status) -> pa.Table:
    """The per-sample table (``uncertainty_samples.parquet``): one row per sample and
    line, built column by column (tens of thousands of samples times every line would
    be millions of Python rows).  ``value`` is what the statistics count (``inf`` out of
    the model), ``record_value`` the RSS of the records as computed (finite for an
    unstable loop whose records stayed within the rails), ``unstable`` the flag."""
    cols = {k: [] for k in ("configuration", "instrument", "axis", "metric", "window")}
    xs, records, flags = [], [], []
    for (ci, cf, inst, axis, kind, window, x), rec in zip(
            _budgets(campaign, ctx, _counted(values, status)),
            _budgets(campaign, ctx, values)):
        for k, v in zip(cols, (cf, inst, axis, kind, window)):
            cols[k].append(v)
        xs.append(x)
        records.append(rec[-1])
        flags.append((status[:, ci] & UNSTABLE) > 0)
    n, k = values.shape[0], len(xs)
    rep = np.repeat(np.arange(k), n)     # line of each row, samples within a line
    table = {"sample": pa.array(np.tile(np.arange(n, dtype=np.int64), k))}
    for name, v in cols.items():
        table[name] = pa.array(v).take(pa.array(rep))
    table["unit"] = pa.array([campaign.unit] * (n * k), pa.string())
    for name, v, t in (("value", xs, pa.float64()), ("record_value", records, pa.float64()),
                       ("unstable", flags, pa.bool_())):
        table[name] = pa.array(np.concatenate(v) if v else np.zeros(0, bool), t)
    return pa.table(table)


def _lines(campaign, ctx, draws, values, status) -> tuple:
    """``(lines, summary)``: the statistics of every line (configuration, instrument,
    axis, metric), an unstable sample counted as exceeding every requirement, and the
    summary rows."""
    from ..analysis.uncertainty import statistics

    unc = campaign.uncertainty
    scalar = draws.scalar_inputs()
    lines, summary = [], []
    for ci, cf, inst, axis, kind, window, x in _budgets(campaign, ctx,
                                                         _counted(values, status)):
        ok = ~np.isnan(x)
        req = campaign.requirement(inst, axis, kind, window)
        st = statistics(x[ok], unc["confidence"], req,
                        inputs={nm: v[ok] for nm, v in scalar.items()},
                        seed=unc["seed"], assurance=unc.get("assurance", 0.95)
                        ) if ok.any() else {}
        # the ten inputs of either ranking that lead it, with both measures
        keep = set(list(st.get("sensitivity", {}))[:10]) | set(list(st.get("first_order", {}))[:10])
        for key in ("sensitivity", "first_order"):
            st[key] = {k: val for k, val in st.get(key, {}).items() if k in keep}
        lines.append({"configuration": cf, "instrument": inst, "axis": axis,
                      "metric": kind, "window": window, "unit": campaign.unit,
                      "requirement": req, "samples_used": int(ok.sum()),
                      "unstable": int(np.sum(status[:, ci] & UNSTABLE > 0)),
                      "limit_reached": int(np.sum(status[:, ci] & LIMIT > 0)), **st})
        for pc, q in st.get("quantiles", {}).items():
            summary.append({"configuration": cf, "instrument": inst, "axis": axis,
                            "metric": kind, "window": window, "unit": campaign.unit,
                            "confidence": pc, "value": q["value"],
                            "boot_low": q["low"], "boot_high": q["high"],
                            "converged": q["converged"],
                            "samples_for_2pct": q["samples_for_2pct"],
                            "assurance": st["assurance"],
                            "upper_bound": q["upper_bound"],
                            "samples_for_bound": q["samples_for_bound"],
                            "requirement": req,
                            "meets_assured": q.get("meets_assured"),
                            "p_meet": st.get("p_meet", math.nan),
                            "p_meet_low": st.get("p_meet_low", math.nan)})
    return lines, summary


def _needs(lines, unknown=math.inf) -> dict:
    """Per confidence level, the sample count that would narrow every finite, unconverged
    value to 2 %, a value whose count cannot be estimated counting as ``unknown`` (left
    out when None); a level with none is left out.  An infinite value (more samples
    outside the model than ``1 - P_c``) has no width: it is left out."""
    need = {}
    for line in lines:
        for pc, q in line.get("quantiles", {}).items():
            if math.isfinite(q["value"]) and not q["converged"]:
                k = q["samples_for_2pct"]
                if k is None:
                    if unknown is None:
                        continue
                    k = unknown
                need[pc] = max(need.get(pc, 0), k)
    return need


def _convergence(lines) -> tuple:
    """``(widest, need)``: the widest relative bootstrap interval of a finite value over
    every line and level (None without one), and the sample count that would narrow
    every one to 2 % (None when all are below it)."""
    widths = [q["rel_width"] for line in lines for q in line.get("quantiles", {}).values()
              if math.isfinite(q["value"])]
    need = _needs(lines)
    return (max(widths) if widths else None), (max(need.values()) if need else None)


def convergence_hint(report: dict) -> str | None:
    """What converging the run would take, in one sentence (None when every finite value
    is converged or no count can be estimated).

    Per confidence level, the sample count that narrows every finite value's bootstrap
    interval below 2 % and the time the samples beyond this run's would take at its own
    rate (its wall time over the samples it computed, start-up included: an estimate);
    and the levels whose upper bounds at the run's assurance already hold.

    Parameters
    ----------
    report : dict
        The content of ``uncertainty.json``.

    Returns
    -------
    str or None
    """
    n = report["samples"]
    need = {pc: int(k) for pc, k in _needs(report["lines"], unknown=None).items() if k > n}
    if not need:
        return None
    computed = n - (report.get("resumed") or 0)
    rate = report["wall_s"] / computed if computed > 0 and report.get("wall_s") else None
    parts = []
    for pc, k in sorted(need.items(), key=lambda kv: float(kv[0])):
        when = f", {_duration((k - n) * rate)} more" if rate else ""
        parts.append(f"P{100 * float(pc):g} about {k:,} samples{when}")
    # the unconverged levels whose distribution-free bounds exist at this count
    bounded = sorted({float(pc) for line in report["lines"]
                      for pc, q in line.get("quantiles", {}).items()
                      if pc in need and q.get("upper_rank") is not None})
    return ("to narrow every finite value's interval below 2 %: " + "; ".join(parts)
            + (f" (at this run's {rate:.2g} s a sample; more workers or a Dask cluster "
               "divide it)" if rate else "")
            + f"; --samples N with the same --out keeps these {n}"
            + (f"; meanwhile the upper bounds at {100 * report['assurance']:g} % assurance "
               "hold at this count (" + ", ".join(f"P{100 * pc:g}" for pc in bounded)
               + ")" if bounded and report.get("assurance") else ""))


def _duration(seconds: float) -> str:
    """``seconds`` for a reader: s, min or h."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def _report(campaign, ctx, draws, status, lines, folder, out_dir, rounds, wall) -> dict:
    """The content of ``uncertainty.json``."""
    from ..analysis.uncertainty import ASSURANCE, INTERPRETATION

    unc = campaign.uncertainty
    configs = ctx["configs"]
    return {"samples": draws.n, "seed": unc["seed"], "confidence": list(unc["confidence"]),
            "assurance": unc.get("assurance", 0.95), "bounds": ASSURANCE,
            "interpretation": INTERPRETATION, "engine": unc.get("engine", "linear"),
            "max_samples": unc.get("max_samples"), "rounds": rounds,
            "parameters": [{"name": it.name, "kind": it.kind, "instances":
                            list(it.instances), "per_mode": it.per_mode,
                            "band": list(it.band),
                            "distribution": None if it.distribution is None else
                            dataclasses.asdict(it.distribution)}
                           for it in unc["parameters"]],
            **{key: {cf: int(np.sum(status[:, ci] & bit > 0)) for ci, cf in enumerate(configs)}
               for key, bit in _STATUS.items()},
            "stability": _stability(status, configs, unc.get("assurance", 0.95)),
            "drivers": _drivers(status, configs, draws.scalar_inputs()),
            "status_means": "unstable: the sample's closed loop has a pole outside the unit "
                            "circle, and the sample counts as exceeding every requirement "
                            "(its records, evaluated as the co-simulation would give them, "
                            "are the record_value of the per-sample table); "
                            "diverging_in_record: that pole more than doubles over the "
                            "record; limit_reached: a record reached a rail or limit, and "
                            "the sample counts as exceeding every requirement",
            "wall_s": time.perf_counter() - wall,
            "resumed": rounds[0]["resumed"], "kept_in": str(folder or Path(out_dir) /
                                                            "uncertainty_cases"),
            "memory": "per sample: the metrics of each record; one record at a time",
            "lines": lines}


def _drivers(status, configs, scalar, top: int = 5) -> dict:
    """Per status (``unstable``, ``limit_reached``) and configuration, the uncertain
    inputs most related to it: rank correlation of each input with the sample's flag
    (largest magnitude first, ``top`` of them); a configuration where no sample or every
    sample has the flag has none."""
    from ..analysis.uncertainty import rank_correlation

    out = {}
    for key, bit in (("unstable", UNSTABLE), ("limit_reached", LIMIT)):
        out[key] = {}
        for ci, cf in enumerate(configs):
            flag = ((status[:, ci] & bit) > 0).astype(float)
            if 0 < flag.sum() < flag.size:
                rho = {name: rank_correlation(v, flag) for name, v in scalar.items()}
                out[key][cf] = dict(sorted(rho.items(), key=lambda kv: -abs(kv[1]))[:top])
    return out


def unstable_upper_bound(unstable: int, n: int, assurance: float = 0.95) -> float:
    """One-sided Clopper-Pearson upper bound of the probability of an unstable loop.

    The complement of the lower bound of the stable probability
    (:func:`orchestrator.analysis.uncertainty.proportion_lower_bound`): ``1 - (1 -
    assurance)**(1/n)`` without an unstable sample, 1 when every sample is unstable.

    Parameters
    ----------
    unstable, n : int
        Unstable samples and samples, ``0 <= unstable <= n``, ``n >= 1``.
    assurance : float
        The probability that the bound lies above the true probability, in (0, 1).

    Returns
    -------
    float
    """
    from ..analysis.uncertainty import proportion_lower_bound

    return 1.0 - proportion_lower_bound(n - unstable, n, assurance)


def _stability(status, configs, assurance) -> dict:
    """Per configuration: samples, unstable ones, the stable fraction, the upper bound
    of the probability of instability at ``assurance``, and the samples counted as
    exceeding every requirement (unstable or reaching a limit)."""
    out = {}
    for ci, cf in enumerate(configs):
        n, k = status.shape[0], int(np.sum(status[:, ci] & UNSTABLE > 0))
        out[cf] = {"samples": n, "unstable": k, "stable_fraction": (n - k) / n,
                   "unstable_upper_bound": unstable_upper_bound(k, n, assurance),
                   "failing_every_requirement": int(np.sum(status[:, ci]
                                                           & (UNSTABLE | LIMIT) > 0))}
    return out


def unbounded_words(line: dict) -> str:
    """Why a line's value is infinite, for a reader: "unbounded: 5 of 20 samples
    unstable" (and how many more reached a rail or limit).

    Parameters
    ----------
    line : dict
        A line of ``uncertainty.json`` (``n``, ``n_infinite``, ``unstable``).

    Returns
    -------
    str
    """
    n, out, k = line.get("n", 0), line.get("n_infinite", 0), line.get("unstable", 0)
    if not k:
        return f"unbounded: {out} of {n} samples reached a rail or limit"
    more = out - k
    return (f"unbounded: {k} of {n} samples unstable"
            + (f", {more} more reached a rail or limit" if more > 0 else ""))


def _value_words(q: dict, line: dict, unit: str) -> str:
    """A level's value with its convergence and its upper bound, for a command line."""
    pc = f"P{100 * float(q['pc']):g}"
    if not math.isfinite(q["value"]):
        return f"{pc} {unbounded_words(line)}"
    text = f"{pc} = {q['value']:.4g} {unit}" + ("" if q["converged"] else (
        " (not converged" + (f"; about {q['samples_for_2pct']} samples would be)"
                             if q.get("samples_for_2pct") else ")")))
    assurance = line.get("assurance")
    if assurance is None or "upper_bound" not in q:
        return text
    at = f"{100 * assurance:g} % assurance"
    if q.get("upper_rank") is None:
        return text + f" (no bound at {at} below {q['samples_for_bound']} samples)"
    if not math.isfinite(q["upper_bound"]):
        return text + f", its bound at {at} unbounded"
    return text + f" <= {q['upper_bound']:.4g} at {at}"


def command_lines(report: dict) -> list:
    """What ``jitterfmu campaign`` prints of a Monte Carlo, one string a line.

    Per configuration with unstable or limited samples, their counts and the upper
    bound of the probability of instability; per line, every level's value (an infinite
    one as :func:`unbounded_words`, never beside "meets"), and against a requirement
    the probability of meeting it with its lower bound and, per level, meets or fails.

    Parameters
    ----------
    report : dict
        The content of ``uncertainty.json``.

    Returns
    -------
    list of str
    """
    out = []
    stability = report.get("stability") or {}
    for cf, k in report["unstable"].items():
        lim = report["limit_reached"][cf]
        if not (k or lim):
            continue
        st = stability.get(cf)
        bound = ("" if st is None else f", probability of instability <= "
                 f"{st['unstable_upper_bound']:.3g} at {100 * report['assurance']:g} %")
        out.append(f"  {cf}: {k} of {report['samples']} sample(s) with an unstable loop "
                   f"({report['diverging_in_record'][cf]} doubling within the record"
                   f"{bound}), {lim} reaching a rail or limit; both counted as exceeding "
                   "every requirement")
    for line in report["lines"]:
        unit = line["unit"]
        qs = ", ".join(_value_words({**q, "pc": pc}, line, unit)
                       for pc, q in line.get("quantiles", {}).items())
        meet = ""
        if "p_meet" in line:
            meet = (f"; requirement {line['requirement']:g} {unit}: P(meet) = "
                    f"{line['p_meet']:.3f}"
                    + (f" (>= {line['p_meet_low']:.3f} at {100 * line['assurance']:g} % "
                       "assurance)" if "p_meet_low" in line else "")
                    + "".join(f", {'meets' if q.get('meets') else 'fails'} at "
                              f"P{100 * float(pc):g}"
                              for pc, q in line.get("quantiles", {}).items()))
        out.append(f"  {line['configuration']:<16} {line['instrument']:>6}/"
                   f"{line['axis']:<6} {qs}{meet}")
    return out


def write_results(out_dir, campaign, ctx, values, status, summary, report) -> Path:
    """Write a Monte Carlo's files into its campaign folder; ``uncertainty.json``.

    Parameters
    ----------
    out_dir : path-like
        The campaign folder.
    campaign : Campaign
        With ``uncertainty`` set.
    ctx : dict
        Its lines, configurations and events (``montecarlo._layout``).
    values : ndarray, shape (n, configs, events, lines, metrics)
        Every record's metric values (rad; ``inf`` out of the model), as computed.
    status : ndarray of int, shape (n, configs)
        The status bits of every sample and configuration.
    summary : list of dict
        The summary rows (:func:`_lines`).
    report : dict
        The content of ``uncertainty.json`` (:func:`_report`).

    Returns
    -------
    Path
    """
    import json

    from .store import write_json, write_table

    out = Path(out_dir)
    write_table(_samples_table(campaign, ctx, values, status), out / SAMPLES_FILE)
    write_table(pa.Table.from_pylist(summary), out / "uncertainty_summary.csv", csv=True)
    write_json(out / UNCERTAINTY_FILE, json.loads(json.dumps(report, default=float)))
    return out / UNCERTAINTY_FILE
