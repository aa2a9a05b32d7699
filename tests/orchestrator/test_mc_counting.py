"""A Monte Carlo counts what its samples are: an unstable loop fails every requirement.

A synthetic Monte Carlo (known per-record metrics and status bits, no FMU) goes through
the same statistics, files, command lines and report as a run's: its unstable samples
count as failing however small their records stayed, an infinite value never meets, and
the report's verdict opens with a Monte Carlo line per configuration.  References: the
one-sided Clopper-Pearson bounds from the beta distribution (scipy.stats.beta), the
counts built into the samples, Spearman's correlation (scipy.stats.spearmanr).
"""

from __future__ import annotations

import json
import math
import re
import time

import numpy as np
import pyarrow.parquet as pq
import pytest
from scipy.stats import beta, spearmanr

from orchestrator.analysis.uncertainty import draw, statistics
from orchestrator.campaign import ANGLE_UNITS, campaign_from_dict, run_campaign
from orchestrator.campaign.mcresults import (UNSTABLE, _lines, _report, command_lines,
                                             write_results)
from orchestrator.campaign.montecarlo import _layout
from orchestrator.report import write_report
from tests.orchestrator.test_report import sine_runner

N, N_UNSTABLE, REQ = 60, 15, 1.2      # samples, unstable ones in "isolation on", arcsec


def _campaign():
    base = {"experiment": {"stop": 1.0, "output_interval": 1e-3},
            "fmus": {"dist": {"fmu": "d", "period": 1e-3, "parameters": {}},
                     "ctrl": {"fmu": "c", "period": 1e-3, "parameters": {"gain": 0.0}},
                     "sc": {"fmu": "s", "period": 1e-3}}}
    return campaign_from_dict({
        "campaign": {"name": "mc counting", "scenario": base, "unit": "arcsec"},
        "events": [{"name": "VNIR pointing", "overrides": {"dist.amplitude": 1e-6,
                                                           "dist.frequency": 10.0}},
                   {"name": "SAD", "overrides": {"dist.amplitude": 1e-6,
                                                 "dist.frequency": 5.0}}],
        "configurations": [{"name": "isolation off", "overrides": {"ctrl.gain": 0.0}},
                           {"name": "isolation on", "overrides": {"ctrl.gain": 4.0}}],
        "instruments": [{"name": "SWIR", "axes": {"pitch": "sc.pitch", "yaw": "sc.yaw"}}],
        "metrics": [{"kind": "peak_to_peak", "windows": [0.2]}],
        "requirements": [{"instrument": "SWIR", "metric": "peak_to_peak", "window": 0.2,
                          "value": REQ}],
        "uncertainty": {"samples": N, "seed": 3, "confidence": [0.95],
                        "parameters": [
                            {"name": "g", "kind": "gain", "instances": ["ctrl"],
                             "distribution": "uniform", "low": 0.5, "high": 2.0},
                            {"name": "amp", "kind": "amplitude", "instances": ["dist"],
                             "distribution": "uniform", "low": 0.8, "high": 1.2}]},
    })


@pytest.fixture(scope="module")
def mc(tmp_path_factory):
    """A campaign folder with a synthetic Monte Carlo: every record's peak-to-peak
    between 0.1 and 0.5 arcsec (RSS over two events at most 0.71, below the 1.2
    requirement), and in "isolation on" the 15 samples of largest gain unstable."""
    camp = _campaign()
    out = tmp_path_factory.mktemp("mc") / "camp"
    run_campaign(camp, out, sine_runner, workers=0, progress=False)
    ctx = _layout(camp)
    draws = draw(camp.uncertainty["parameters"], N, camp.uncertainty["seed"])
    rng = np.random.default_rng(11)
    arcsec = rng.uniform(0.1, 0.5, (N, 2, 2, 2, 1))     # samples, configs, events, axes
    values = arcsec / ANGLE_UNITS["arcsec"]             # rad, as the engine gives them
    status = np.zeros((N, 2), int)
    g = draws.values["g"][:, 0]
    unstable = np.argsort(g)[-N_UNSTABLE:]
    status[unstable, 1] = UNSTABLE
    lines, summary = _lines(camp, ctx, draws, values, status)
    rounds = [{"samples": N, "widest_interval": None, "resumed": 0}]
    report = _report(camp, ctx, draws, status, lines, None, out, rounds, time.perf_counter())
    path = write_results(out, camp, ctx, values, status, summary, report)
    rss = np.sqrt(np.sum(arcsec**2, axis=2))[..., 0]     # (N, configs, axes) arcsec
    return {"out": out, "rep": json.loads(path.read_text()), "lines": lines, "rss": rss,
            "g": g, "flag": np.isin(np.arange(N), unstable)}


def _line(lines, cf, axis):
    return next(ln for ln in lines if ln["configuration"] == cf and ln["axis"] == axis)


def test_unstable_samples_fail_every_requirement_however_small_their_records(mc):
    """Every record meets the requirement; the 15 unstable samples of 60 count as
    failing: p_meet 45/60, its lower bound the one-sided Clopper-Pearson bound, and
    neither meets nor meets_assured at P95.  Without them, all 60 meet."""
    assert mc["rss"].max() < REQ                 # the records alone would all meet
    for axis in ("pitch", "yaw"):
        on = _line(mc["lines"], "isolation on", axis)
        assert on["unstable"] == N_UNSTABLE and on["n_infinite"] == N_UNSTABLE
        assert on["p_meet"] == pytest.approx((N - N_UNSTABLE) / N, abs=1e-15)
        # P(Binomial(n, p) >= k) = 0.05 at the bound: the 5 % quantile of Beta(k, n-k+1)
        assert on["p_meet_low"] == pytest.approx(
            beta.ppf(0.05, N - N_UNSTABLE, N_UNSTABLE + 1), rel=1e-9)
        q = on["quantiles"][0.95]
        assert q["value"] == math.inf and not q["meets"] and not q["meets_assured"]
        off = _line(mc["lines"], "isolation off", axis)
        assert off["p_meet"] == 1.0 and off["n_infinite"] == 0
        assert off["p_meet_low"] == pytest.approx(0.05 ** (1 / N), rel=1e-9)
        assert off["quantiles"][0.95]["meets"] and off["quantiles"][0.95]["meets_assured"]


def test_the_files_keep_the_records_and_count_the_unstable_samples(mc):
    """The per-sample table counts an unstable sample as inf and keeps its record's RSS
    beside it; uncertainty.json gives per configuration the unstable count and the
    Clopper-Pearson upper bound of the probability of instability."""
    t = pq.read_table(mc["out"] / "uncertainty_samples.parquet").to_pylist()
    rows = [r for r in t if r["configuration"] == "isolation on" and r["axis"] == "yaw"]
    assert [r["sample"] for r in rows] == list(range(N))
    for r in rows:
        rec = mc["rss"][r["sample"], 1, 1]
        assert r["record_value"] == pytest.approx(rec, rel=1e-12)
        assert r["unstable"] == bool(mc["flag"][r["sample"]])
        assert r["value"] == (math.inf if r["unstable"] else pytest.approx(rec, rel=1e-12))
    st = mc["rep"]["stability"]
    assert st["isolation on"]["unstable"] == N_UNSTABLE == mc["rep"]["unstable"]["isolation on"]
    assert st["isolation on"]["stable_fraction"] == pytest.approx(1 - N_UNSTABLE / N)
    assert st["isolation on"]["failing_every_requirement"] == N_UNSTABLE
    assert st["isolation on"]["unstable_upper_bound"] == pytest.approx(
        beta.ppf(0.95, N_UNSTABLE + 1, N - N_UNSTABLE), rel=1e-9)
    assert st["isolation off"]["unstable"] == 0
    assert st["isolation off"]["unstable_upper_bound"] == pytest.approx(1 - 0.05 ** (1 / N),
                                                                        rel=1e-12)


def test_an_infinite_value_never_meets():
    """19 samples far below the requirement and one out of the model: the fraction
    below it is 0.95 = P_c, but the value at P95 interpolates towards the infinite
    sample and is infinite, so the line does not meet; nor does a finite value above
    the requirement whose fraction below it reaches P_c (the two statements agree)."""
    x = np.concatenate([np.linspace(1.0, 2.0, 19), [np.inf]])
    st = statistics(x, [0.95], 10.0, seed=1)
    q = st["quantiles"][0.95]
    assert st["p_meet"] == pytest.approx(0.95) and q["value"] == math.inf
    assert q["meets"] is False and q["meets_assured"] is False
    # 19 of 20 below 9.5, the last at 30: P95 = 2 + 0.05 x (30 - 2) = 3.4 by linear
    # interpolation of the 19th and 20th order statistics (0.95 x 19 = 18.05)
    y = np.concatenate([np.linspace(1.0, 2.0, 19), [30.0]])
    st = statistics(y, [0.95], 3.0, seed=1)
    assert st["p_meet"] == pytest.approx(0.95)
    assert st["quantiles"][0.95]["value"] == pytest.approx(2.0 + 0.05 * 28.0)
    assert st["quantiles"][0.95]["meets"] is False
    assert statistics(y, [0.95], 3.5, seed=1)["quantiles"][0.95]["meets"] is True


def test_the_command_lines_count_the_unstable_samples_and_never_meet_unbounded(mc):
    lines = command_lines(mc["rep"])
    head = next(t for t in lines if t.lstrip().startswith("isolation on:"))
    bound = beta.ppf(0.95, N_UNSTABLE + 1, N - N_UNSTABLE)
    assert f"{N_UNSTABLE} of {N} sample(s) with an unstable loop" in head
    assert f"<= {bound:.3g} at 95 %" in head
    assert not any(t.lstrip().startswith("isolation off:") for t in lines)
    on = [t for t in lines if "isolation on" in t and "/" in t]
    assert len(on) == 2
    for t in on:
        assert f"P95 unbounded: {N_UNSTABLE} of {N} samples unstable" in t
        assert "meets" not in t and "fails at P95" in t
        assert f"P(meet) = {(N - N_UNSTABLE) / N:.3f}" in t
    off = [t for t in lines if "isolation off" in t]
    assert len(off) == 2 and all("meets at P95" in t and "inf" not in t for t in off)


def test_the_verdict_opens_with_the_monte_carlo_line_of_every_configuration(mc):
    """Stable samples with the upper bound of the probability of instability, P(meet)
    with its lower bound and the 95/95 value of the weakest line; the unbounded value in
    the failing class with the input that drives the instability."""
    text = write_report(mc["out"], "html").read_text(encoding="utf-8")
    verdict = text[text.index("<h2 id='verdict'>Verdict</h2>"):]
    assert verdict.startswith("<h2 id='verdict'>Verdict</h2>\n<ul class='mc'><li>")
    assert verdict.index("<ul class='mc'>") < verdict.index("<table")
    items = re.findall(r"<li>(.*?)</li>", verdict[:verdict.index("</ul>")])
    assert len(items) == 2
    off, on = items
    # off: no unstable sample of 60, bound 1 - 0.05^(1/60); the 95/95 value of 60
    # samples is their largest (1 - 0.95^60 = 0.954 >= 0.95), on the axis of the larger
    assert off.startswith("Monte Carlo, isolation off: 60 of 60 samples stable")
    assert f"probability of instability &lt;= {1 - 0.05 ** (1 / N):.3g} at 95 %" in off
    top = mc["rss"][:, 0].max(axis=0)
    axis = ("pitch", "yaw")[int(np.argmax(top))]
    assert f"weakest line SWIR {axis}" in off
    assert f"95/95 value {top.max():.4g} arcsec" in off and "class='fail'" not in off
    assert f"P(meet {REQ:g} arcsec) = 1.000 (&gt;= {0.05 ** (1 / N):.3f} at 95 %)" in off
    # on: 15 unstable of 60, its probability bounded by the Beta(16, 45) 95 % quantile
    bound = beta.ppf(0.95, N_UNSTABLE + 1, N - N_UNSTABLE)
    assert (f"<span class='fail'>{N - N_UNSTABLE} of {N} samples stable</span> "
            f"(probability of instability &lt;= {bound:.3g} at 95 %)") in on
    low = beta.ppf(0.05, N - N_UNSTABLE, N_UNSTABLE + 1)
    assert f"= {(N - N_UNSTABLE) / N:.3f} (&gt;= {low:.3f} at 95 %)" in on
    assert (f"95/95 value <span class='fail'>unbounded: {N_UNSTABLE} of {N} samples "
            "unstable</span>") in on
    rho = spearmanr(mc["g"], mc["flag"]).statistic
    assert f"g {rho:+.2f}" in on and rho > 0.5 and "inf" not in on
    # the failing class is the verdict table's
    assert "span.fail{" in text or "td.fail,span.fail{" in text
    md = write_report(mc["out"], "md").read_text(encoding="utf-8")
    first = md[md.index("## Verdict"):].splitlines()[2]
    assert first.startswith("- Monte Carlo, isolation off: 60 of 60 samples stable")
    assert f"**unbounded: {N_UNSTABLE} of {N} samples unstable**" in md
