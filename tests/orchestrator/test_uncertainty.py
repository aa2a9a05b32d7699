"""Monte Carlo budgets (orchestrator.analysis.uncertainty, orchestrator.campaign.montecarlo).

References: the closed form of a budget whose only uncertainty is a uniform amplitude
factor (every metric is positively homogeneous: the sample is the factor times the
nominal value, exactly), a ranking where only one input matters, and the order
statistics of a uniform sample.
"""

from __future__ import annotations

import json
from pathlib import Path
import math

import numpy as np
import pytest

from orchestrator.analysis.uncertainty import (Distribution, UncertaintyError, draw,
                                               proportion_lower_bound, quantile_upper_bound,
                                               rank_correlation, samples_for_bound,
                                               statistics)
from orchestrator.campaign.spec import RSS_EVENT
from orchestrator.campaign import (CampaignError, LinearRunner, campaign_from_dict,
                                   run_campaign, run_uncertainty)

ROOT_SCENARIO = "scenarios/truss10_campaign.toml"


def _campaign(uncertainty, configurations=None):
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    return {
        "campaign": {"name": "mc", "scenario": str(root / ROOT_SCENARIO), "unit": "arcsec",
                     "skip": 0.0, "stop": 2.0, "output_interval": 1e-3, "engine": "linear",
                     "verify": 0},
        "events": [{"name": "diagonal", "overrides": {"excitation.amp1": 10.0}}],
        "configurations": configurations or [
            {"name": "on", "overrides": {"ctrl_diag.gain": 1.0, "ctrl_long.gain": 1.0}}],
        "instruments": [{"name": "tip", "axes": {"roll": "structure.los_tip_roll",
                                                 "pitch": "structure.los_tip_pitch"}}],
        "metrics": [{"kind": "peak_to_peak", "windows": [0.5]}, {"kind": "rms"}],
        "requirements": [{"instrument": "tip", "metric": "peak_to_peak", "window": 0.5,
                          "value": 2.0}],
        "uncertainty": uncertainty,
    }


def _amp_and_gain(samples, seed, low, high):
    """An ``[uncertainty]`` table: the excitation's amplitude +-20 % and the diagonal
    loop's gain uniform in ``[low, high]``."""
    return {"samples": samples, "seed": seed, "confidence": [0.95],
            "parameters": [{"name": "amp", "kind": "amplitude", "instances": ["excitation"],
                            "distribution": "uniform", "low": 0.8, "high": 1.2},
                           {"name": "g", "kind": "gain", "instances": ["ctrl_diag"],
                            "distribution": "uniform", "low": low, "high": high}]}


def test_distributions_stay_in_bounds_and_repeat_with_the_seed():
    rng = np.random.default_rng(1)
    for d in (Distribution("uniform", 0.8, 1.2), Distribution("normal", 0.5, 1.5, mean=1.0,
                                                                std=0.3),
              Distribution("lognormal", 0.5, 2.0, median=1.0, sigma=0.5)):
        x = d.sample(rng, 5000)
        assert x.min() >= d.low and x.max() <= d.high
    u = Distribution("uniform", 0.0, 1.0)
    # the uniform's order statistics: the empirical 0.95 quantile of 20000 draws is
    # within 3 standard errors sqrt(p (1 - p) / n) of 0.95
    q = np.quantile(u.sample(np.random.default_rng(2), 20000), 0.95)
    assert abs(q - 0.95) < 3 * math.sqrt(0.95 * 0.05 / 20000)


def test_rank_correlation_of_monotone_and_independent_samples():
    rng = np.random.default_rng(0)
    x = rng.uniform(size=400)
    assert rank_correlation(x, np.exp(3 * x)) == pytest.approx(1.0)
    assert rank_correlation(x, -x**3) == pytest.approx(-1.0)
    assert abs(rank_correlation(x, rng.uniform(size=400))) < 0.2


def test_statistics_quantile_interval_and_probability():
    x = np.random.default_rng(5).uniform(1.0, 2.0, 4000)
    st = statistics(x, [0.95], requirement=1.5, seed=1)
    q = st["quantiles"][0.95]
    assert q["low"] <= q["value"] <= q["high"] and abs(q["value"] - 1.95) < 0.01
    assert q["converged"]                      # the interval is well below 2 % of 1.95
    assert abs(st["p_meet"] - 0.5) < 3 * st["p_meet_se"]
    assert "ensemble" in st["interpretation"]
    assert st["quantiles"][0.95]["meets"] is False       # half the samples exceed 1.5


def test_a_quantile_that_reaches_the_infinite_samples_is_infinite():
    """Samples outside the model are infinite: a level whose quantile interpolates
    towards one of them is infinite too (not a huge finite number), a lower level is
    the quantile of the finite ones."""
    x = np.concatenate([np.linspace(1.0, 2.0, 95), np.full(5, np.inf)])
    st = statistics(x, [0.5, 0.95, 0.99], seed=1)
    assert st["n_infinite"] == 5
    assert st["quantiles"][0.5]["value"] == pytest.approx(np.quantile(x[:95], 0.5 / 0.95),
                                                          rel=0.02)
    assert st["quantiles"][0.95]["value"] == math.inf == st["quantiles"][0.99]["value"]
    assert not st["quantiles"][0.95]["converged"]
    assert st["quantiles"][0.95]["samples_for_2pct"] is None


def test_the_fewest_samples_for_a_bound_are_wilks_counts():
    """The largest of n samples lies above the p-quantile with probability 1 - p^n:
    59 samples for 95 % at 95 % (Wilks), 459 for 99 % at 99 %, 1109 for 99.73 % at 95 %."""
    assert samples_for_bound(0.95, 0.95) == 59 and 1 - 0.95**58 < 0.95 <= 1 - 0.95**59
    assert samples_for_bound(0.99, 0.99) == 459
    assert samples_for_bound(0.9973, 0.95) == 1109
    x = np.arange(1.0, 59.0)                  # 58 samples: no bound yet
    assert quantile_upper_bound(x, 0.95, 0.95) == (math.inf, None, 59)
    assert quantile_upper_bound(np.arange(1.0, 60.0), 0.95, 0.95) == (59.0, 59, 59)


def test_the_upper_bound_covers_the_true_quantile_as_often_as_it_says():
    """Coverage against the closed form: for 200 uniform samples the bound is the k-th
    order statistic with P(Binomial(200, 0.9) <= k - 1) >= 0.9 (the smallest such k),
    and over 4000 independent runs it lies above the true 0.9-quantile (0.9) in that
    fraction of them, within four binomial standard errors; the sample quantile itself
    lies above it only about half the time."""
    from math import comb
    n, p, a = 200, 0.9, 0.9
    cdf = np.cumsum([comb(n, j) * p**j * (1 - p)**(n - j) for j in range(n + 1)])
    k = int(np.argmax(cdf >= a)) + 1
    rng = np.random.default_rng(3)
    runs = rng.uniform(size=(4000, n))
    hits, plain = 0, 0
    for x in runs:
        b, rank, _ = quantile_upper_bound(x, p, a)
        assert rank == k and b == np.sort(x)[k - 1]
        hits += b >= p
        plain += np.quantile(x, p) >= p
    cover = cdf[k - 1]
    assert abs(hits / 4000 - cover) < 4 * math.sqrt(cover * (1 - cover) / 4000)
    assert cover >= a and plain / 4000 < 0.6


def test_meets_assured_is_the_clopper_pearson_bound_of_p_meet():
    """The order statistic below the requirement and the one-sided Clopper-Pearson
    bound of prob(X < X_max) at or above P_c are one statement (for every requirement
    between the samples); the lower bound is exact at its definition."""
    from scipy.special import bdtr
    x = np.random.default_rng(8).lognormal(0.0, 0.3, 500)
    for req in np.quantile(x, np.linspace(0.85, 0.995, 40)) * 1.0000001:
        st = statistics(x, [0.9, 0.95], req, seed=1)
        for pc, q in st["quantiles"].items():
            assert q["meets_assured"] == (st["p_meet_low"] >= pc)
            assert q["upper_bound"] >= q["value"]
    m = 450
    lo = proportion_lower_bound(m, 500, 0.95)
    assert 1 - bdtr(m - 1, 500, lo) == pytest.approx(0.05, rel=1e-9)
    assert proportion_lower_bound(0, 10) == 0.0
    with pytest.raises(UncertaintyError, match="11 successes of 10 trials"):
        proportion_lower_bound(11, 10)


def test_an_upper_bound_on_a_sample_outside_the_model_is_infinite():
    """Samples outside the model count as above every value: a bound whose rank falls on
    one is infinite, and never meets a requirement."""
    x = np.concatenate([np.linspace(1.0, 2.0, 960), np.full(40, np.inf)])
    st = statistics(x, [0.95], 10.0, seed=1)
    q = st["quantiles"][0.95]
    assert q["upper_rank"] > 960 and q["upper_bound"] == math.inf
    assert math.isfinite(q["value"]) and q["meets"] and not q["meets_assured"]


@pytest.fixture(scope="module")
def truss_fmus(suite_fmus, suite_fmu_dir):
    from tests.orchestrator.test_truss10_campaign import FMUS
    suite_fmus(*FMUS)
    return suite_fmu_dir


def _run(tmp_path, data, fmu_dir):
    camp = campaign_from_dict(data)
    runner = LinearRunner(camp.scenario_dir, fmu_dir=fmu_dir)
    run_campaign(camp, tmp_path, runner, progress=False)
    path = run_uncertainty(camp, tmp_path, runner, progress=False)
    return camp, json.loads(path.read_text())


@pytest.mark.slow
def test_uniform_amplitude_gives_the_closed_form_budget(tmp_path, truss_fmus):
    """Jitter = factor x nominal for every sample: the 95 % value is the nominal times
    the factor's own 95 % quantile, and P(meet) that of the uniform."""
    import pyarrow.parquet as pq
    unc = {"samples": 400, "seed": 11, "confidence": [0.95],
           "parameters": [{"name": "amp", "kind": "amplitude", "instances": ["excitation"],
                           "distribution": "uniform", "low": 0.8, "high": 1.2}]}
    camp, rep = _run(tmp_path, _campaign(unc), truss_fmus)
    nominal = {(r["instrument"], r["axis"], r["metric"]): r["value"]
               for r in pq.read_table(tmp_path / "summary.parquet").to_pylist()
               if r["event"] == "RSS"}
    factors = draw(camp.uncertainty["parameters"], 400, 11).values["amp"][:, 0]
    samples = pq.read_table(tmp_path / "uncertainty_samples.parquet").to_pylist()
    for line in rep["lines"]:
        key = (line["instrument"], line["axis"], line["metric"])
        x = np.array([s["value"] for s in samples if (s["instrument"], s["axis"],
                                                      s["metric"]) == key])
        np.testing.assert_allclose(x, nominal[key] * factors, rtol=1e-9)
        q = line["quantiles"]["0.95"]["value"]
        assert abs(q / nominal[key] - (0.8 + 0.4 * 0.95)) < 0.01
        # the 95/95 bound is the nominal times the factors' own order statistic
        b, rank, _ = quantile_upper_bound(factors, 0.95, 0.95)
        assert line["quantiles"]["0.95"]["upper_bound"] == pytest.approx(nominal[key] * b,
                                                                         rel=1e-9)
        assert line["quantiles"]["0.95"]["upper_rank"] == rank and line["assurance"] == 0.95
        if line["metric"] == "peak_to_peak":
            want = min(max((2.0 / nominal[key] - 0.8) / 0.4, 0.0), 1.0)
            assert abs(line["p_meet"] - want) <= 3 * max(line["p_meet_se"], 1 / 400)
        top = next(iter(line["sensitivity"]))
        assert top == "amp" and line["sensitivity"]["amp"] == pytest.approx(1.0)


@pytest.mark.slow
def test_sensitivity_names_the_only_input_that_matters(tmp_path, truss_fmus):
    """The longeron's loop is at gain 0 in this configuration: a factor on it changes
    nothing, the modal frequencies do."""
    unc = {"samples": 40, "seed": 4, "confidence": [0.95],
           "parameters": [
               {"name": "freq", "kind": "modal_frequency", "distribution": "uniform",
                "low": 0.9, "high": 1.1},
               {"name": "dead gain", "kind": "gain", "instances": ["ctrl_long"],
                "distribution": "uniform", "low": 0.5, "high": 1.5}]}
    cfg = [{"name": "diag only", "overrides": {"ctrl_diag.gain": 1.0, "ctrl_long.gain": 0.0}}]
    _, rep = _run(tmp_path, _campaign(unc, cfg), truss_fmus)
    for line in rep["lines"]:
        sens = line["sensitivity"]
        assert abs(sens["freq"]) > 0.5
        assert abs(sens["dead gain"]) < 0.35
        # the first-order index agrees: with 40 samples (2 bins) an input that does not
        # matter scatters about 0 by about 0.04 (the 2-bin correlation ratio of
        # independent samples, chi^2 with 1 degree of freedom over 39)
        first = line["first_order"]
        assert first["dead gain"] < 0.2 and first["freq"] > first["dead gain"]
        assert line["samples_used"] == 40


@pytest.mark.parametrize("unc, words", [
    ({"samples": 0, "parameters": [{"kind": "phase", "instances": ["a"]}]},
     "samples is 0; expected a whole number >= 1"),
    ({"parameters": [{"kind": "modal_damping", "distribution": "beta", "low": 0.5,
                      "high": 2}]}, "has distribution 'beta'; expected one of"),
    ({"parameters": [{"kind": "modal_damping", "distribution": "uniform", "low": -0.5,
                      "high": 2}]}, "give it bounds low >= 0"),
    ({"parameters": [{"kind": "frequency", "instances": ["a"], "distribution": "normal",
                      "mean": 1.0, "std": 0.02}]}, "can reach -inf; give it bounds low > 0"),
    ({"parameters": [{"kind": "amplitude", "instances": ["nope"], "distribution": "uniform",
                      "low": 0.5, "high": 2}]}, "instances is \\['nope'\\]"),
    ({"parameters": [{"kind": "stiffness", "distribution": "uniform", "low": 0.5,
                      "high": 2}]}, "kind 'stiffness'; expected one of"),
    ({"parameters": [{"kind": "gain", "instances": ["a"], "distribution": "normal",
                      "mean": 1.0, "std": 0.0}]}, "std > 0"),
    ({"parameters": []}, "needs 'parameters'"),
    ({"assurance": 1.0, "parameters": [{"kind": "phase", "instances": ["a"]}]},
     "assurance is 1.0; expected the probability in \\(0, 1\\)"),
    ({"samples": 100, "max_samples": 50, "parameters": [
        {"kind": "phase", "instances": ["a"]}]}, "max_samples is 50; expected a whole "
                                                 "number >= samples \\(100\\)"),
])
def test_bad_uncertainty_is_one_sentence_before_any_case(unc, words):
    data = {"campaign": {"name": "x", "scenario": {
        "experiment": {"stop": 0.1}, "fmus": {"a": {"fmu": "x.fmu", "period": 1e-3}}}},
        "instruments": [{"name": "i", "axes": {"x": "a.y"}}], "uncertainty": unc}
    with pytest.raises(CampaignError, match=words):
        campaign_from_dict(data)


def test_modal_band_without_modes_is_refused():
    from orchestrator.analysis.uncertainty import Uncertain
    it = Uncertain("f", "modal_frequency", Distribution("uniform", 0.9, 1.1), band=(500, 600))
    with pytest.raises(UncertaintyError, match="no mode in the band"):
        draw([it], 3, 0, np.array([8.4, 9.5]))


@pytest.mark.slow
def test_pool_and_dask_give_the_same_samples(tmp_path, truss_fmus):
    """Samples split over two worker processes, and over a Dask cluster, are the samples
    of one process, to the last bit."""
    import dataclasses

    import distributed
    import pyarrow.parquet as pq

    unc = {"samples": 8, "seed": 2, "confidence": [0.95],
           "parameters": [{"name": "freq", "kind": "modal_frequency", "per_mode": True,
                           "distribution": "uniform", "low": 0.97, "high": 1.03}]}
    camp = campaign_from_dict(_campaign(unc))
    got = {}
    for mode in ("serial", "pool", "dask"):
        out = tmp_path / mode
        runner = LinearRunner(camp.scenario_dir, fmu_dir=truss_fmus)
        run_campaign(dataclasses.replace(camp), out, runner, progress=False)
        if mode == "dask":
            with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                          dashboard_address=None) as cluster:
                run_uncertainty(camp, out, runner, progress=False,
                                scheduler=cluster.scheduler_address)
        else:
            run_uncertainty(camp, out, runner, progress=False,
                            workers=2 if mode == "pool" else 0)
        got[mode] = [r["value"] for r in
                     pq.read_table(out / "uncertainty_samples.parquet").to_pylist()]
    assert got["pool"] == got["serial"] and got["dask"] == got["serial"]


@pytest.mark.slow
def test_max_samples_extends_the_run_until_its_values_converge(tmp_path, truss_fmus):
    """From 40 samples, a uniform amplitude (jitter = factor x nominal): each round adds
    the samples its widest interval asks for, and the run stops once every 95 % value's
    bootstrap interval is below 2 %, well before max_samples. The samples are the
    per-sample draws: a plain run of the final count gives the same numbers; and its
    95 % values are the closed form's (nominal x (0.8 + 0.4 x 0.95)) within 2 %."""
    import pyarrow.parquet as pq
    unc = {"samples": 40, "max_samples": 5000, "seed": 3, "confidence": [0.95],
           "parameters": [{"name": "amp", "kind": "amplitude", "instances": ["excitation"],
                           "distribution": "uniform", "low": 0.8, "high": 1.2}]}
    _, rep = _run(tmp_path / "grown", _campaign(unc), truss_fmus)
    counts = [r["samples"] for r in rep["rounds"]]
    assert counts[0] == 40 and counts == sorted(set(counts)) and len(counts) >= 2
    assert rep["samples"] == counts[-1] < 5000
    assert rep["rounds"][-1]["widest_interval"] < 0.02 <= rep["rounds"][-2]["widest_interval"]
    assert all(q["converged"] for line in rep["lines"] for q in line["quantiles"].values())
    assert rep["rounds"][1]["resumed"] == 40     # the first round's samples were kept
    nominal = {(r["instrument"], r["axis"], r["metric"]): r["value"]
               for r in pq.read_table(tmp_path / "grown" / "summary.parquet").to_pylist()
               if r["event"] == "RSS"}
    for line in rep["lines"]:
        want = nominal[(line["instrument"], line["axis"], line["metric"])] * (0.8 + 0.38)
        assert line["quantiles"]["0.95"]["value"] == pytest.approx(want, rel=0.02)
    plain = dict(unc, samples=rep["samples"])
    del plain["max_samples"]
    _, once = _run(tmp_path / "once", _campaign(plain), truss_fmus)
    a = pq.read_table(tmp_path / "grown" / "uncertainty_samples.parquet").to_pylist()
    b = pq.read_table(tmp_path / "once" / "uncertainty_samples.parquet").to_pylist()
    assert a == b and once["lines"] == rep["lines"]


@pytest.mark.slow
def test_unstable_samples_are_counted_and_fail_once_out_of_the_model(tmp_path, truss_fmus):
    """Gains 1 to 6 times the design: the loop goes unstable once the diagonal's factor
    passes about 2.5 (its largest pole |z| = 1.10 per super-period at 3 x, 2.6 at 5 x,
    with the longeron at 1 x; stable at 2 x) and diverges within 2 s; every such sample
    is counted and fails every requirement, as do those whose records reach a rail."""
    unc = {"samples": 30, "seed": 9, "confidence": [0.5],
           "parameters": [{"name": "g", "kind": "gain", "instances": ["ctrl_diag",
                                                                       "ctrl_long"],
                           "distribution": "uniform", "low": 1.0, "high": 6.0}]}
    camp, rep = _run(tmp_path, _campaign(unc), truss_fmus)
    k = rep["unstable"]["on"]
    assert 0 < k < 30 and rep["diverging_in_record"]["on"] <= k
    lim = rep["limit_reached"]["on"]
    out = rep["stability"]["on"]["failing_every_requirement"]
    assert max(k, lim) <= out <= k + lim
    for line in rep["lines"]:
        assert line["unstable"] == k and line["n_infinite"] == out
        if "p_meet" in line:
            assert line["p_meet"] <= 1 - out / 30 + 1e-12
    # the records of the unstable samples stay in the per-sample table
    import pyarrow.parquet as pq
    rows = pq.read_table(tmp_path / "uncertainty_samples.parquet").to_pylist()
    assert sum(r["unstable"] for r in rows) == k * len(rep["lines"])
    assert all(r["value"] == math.inf for r in rows if r["unstable"])
    # an unstable sample whose records stayed within the rails keeps a finite record:
    # |unstable \ limited| = |unstable or limited| - |limited| of them, in every line
    assert sum(math.isfinite(r["record_value"]) for r in rows if r["unstable"]) == (
        (out - lim) * len(rep["lines"]))
    # the diagonal's factor decides it: the input most related to the unstable samples.
    # A flag exactly above factor 2.5 of a uniform on [1, 6] (p = 0.7) has the rank
    # correlation sqrt(3 p (1 - p)) = 0.79 with it; 0.6 leaves two standard errors of a
    # 30-sample estimate (about 0.1 each)
    drivers = rep["drivers"]["unstable"]["on"]
    assert next(iter(drivers)) == "g [ctrl_diag]" and drivers["g [ctrl_diag]"] > 0.6
    assert abs(drivers["g [ctrl_long]"]) < drivers["g [ctrl_diag]"]
    from orchestrator.report_sweeps import uncertainty_sections
    text = uncertainty_sections(tmp_path, camp.instruments, camp.unit)[2]
    assert (f"on: {k} sample(s) with an unstable closed loop" in text
            and "most related input: g [ctrl_diag], rank correlation +" in text)
    assert "on: the input that explains most of a budget alone is g [" in text
    # and which engine the samples ran on, with its reason
    assert " on: dense loop (the coupling of 'structure' with the rest of the loop" in text


@pytest.mark.slow
def test_cosimulated_samples_equal_the_linear_ones(tmp_path, truss_fmus):
    """engine = "cosim": every sample, configuration and event a co-simulated case with
    the draws as overrides; the same samples as the linear engine's, to 1e-9."""
    import pyarrow.parquet as pq
    unc = {"samples": 3, "seed": 5, "confidence": [0.5],
           "parameters": [{"name": "g", "kind": "gain", "instances": ["ctrl_diag"],
                           "distribution": "uniform", "low": 0.5, "high": 1.5}]}
    got = {}
    for engine in ("linear", "cosim"):
        _, rep = _run(tmp_path / engine, _campaign({**unc, "engine": engine}), truss_fmus)
        assert rep["engine"] == engine
        got[engine] = np.array([r["value"] for r in pq.read_table(
            tmp_path / engine / "uncertainty_samples.parquet").to_pylist()])
    assert (tmp_path / "cosim" / "uncertainty_cases" / "summary.parquet").is_file()
    np.testing.assert_allclose(got["cosim"], got["linear"], rtol=1e-9)


def test_cosimulated_modal_uncertainty_is_refused():
    data = {"campaign": {"name": "x", "scenario": {
        "experiment": {"stop": 0.1}, "fmus": {"a": {"fmu": "x.fmu", "period": 1e-3}}}},
        "instruments": [{"name": "i", "axes": {"x": "a.y"}}],
        "uncertainty": {"engine": "cosim", "parameters": [
            {"name": "f", "kind": "modal_frequency", "distribution": "uniform",
             "low": 0.9, "high": 1.1}]}}
    with pytest.raises(CampaignError, match="'f' moves the structure's modes.*linear engine"):
        campaign_from_dict(data)


def test_draws_are_per_sample_so_more_samples_extend_the_same_ones():
    """Sample s is the same draw whatever the count: a run can be extended or resumed."""
    from orchestrator.analysis.uncertainty import Uncertain
    items = (Uncertain("f", "modal_frequency", Distribution("normal", 0.9, 1.1, mean=1.0,
                                                            std=0.05), per_mode=True),
             Uncertain("p", "phase", None, instances=("a", "b")),
             Uncertain("g", "gain", Distribution("uniform", 0.5, 1.5), instances=("c",)))
    freqs = np.array([0.0, 1.0, 2.0, 3.0])
    few, many = draw(items, 7, 3, freqs), draw(items, 40, 3, freqs)
    for name, v in few.values.items():
        assert v.shape[0] == 7 and np.array_equal(v, many.values[name][:7])
    assert not np.array_equal(draw(items, 7, 4, freqs).values["g"], few.values["g"])
    with pytest.raises(UncertaintyError, match="seed is -1; expected a whole number >= 0"):
        draw(items, 3, -1, freqs)


def test_samples_needed_for_a_two_percent_interval():
    """The bootstrap interval narrows as 1/sqrt(n): at the count statistics() names from
    1000 samples, fresh samples' intervals are about 2 %.  Tolerance: the width of one
    1000-sample interval scatters by about 25 % (measured over seeds), so the count by
    about 55 % and the width at that count by about 25 %: [1.3 %, 3 %] holds it."""
    rng = np.random.default_rng(8)
    q = statistics(rng.lognormal(0.0, 0.2, 1000), [0.95], seed=2)["quantiles"][0.95]
    assert not q["converged"] and q["samples_for_2pct"] > 1000
    n = q["samples_for_2pct"]
    widths = [statistics(rng.lognormal(0.0, 0.2, n), [0.95], seed=s)["quantiles"][0.95]
              ["rel_width"] for s in range(3)]
    assert 0.013 < np.median(widths) < 0.03, (n, widths)


def _unc_campaign():
    return _campaign({"samples": 10, "seed": 6, "confidence": [0.95],
                      "parameters": [{"name": "freq", "kind": "modal_frequency",
                                      "per_mode": True, "distribution": "uniform",
                                      "low": 0.97, "high": 1.03},
                                     {"name": "amp", "kind": "amplitude",
                                      "instances": ["excitation"],
                                      "distribution": "uniform", "low": 0.8,
                                      "high": 1.2}]})


def _samples(folder):
    import pyarrow.parquet as pq
    return [r["value"] for r in pq.read_table(folder / "uncertainty_samples.parquet").to_pylist()]


@pytest.mark.slow
def test_a_stopped_run_keeps_its_samples_and_resumes_to_the_same_numbers(
        tmp_path, truss_fmus, monkeypatch, capsys):
    """Stopped after its first chunk, a run says what it kept; the same call again runs
    only the rest, and the result is that of an uninterrupted run to the last bit; a
    larger count extends it; a kept part that is not ours is named and run again."""
    import dataclasses

    from orchestrator.campaign import CampaignInterrupted
    from orchestrator.campaign import montecarlo as mc

    data = _unc_campaign()
    camp = campaign_from_dict(data)
    runner = LinearRunner(camp.scenario_dir, fmu_dir=truss_fmus)
    whole = tmp_path / "whole"
    run_campaign(camp, whole, runner, progress=False)
    run_uncertainty(camp, whole, runner, progress=False)

    out = tmp_path / "stopped"
    run_campaign(camp, out, runner, progress=False)
    real, calls = mc._evaluate, []

    def stop_after_one(*args):
        if calls:
            raise KeyboardInterrupt
        calls.append(1)
        return real(*args)

    monkeypatch.setattr(mc, "_evaluate", stop_after_one)
    with pytest.raises(CampaignInterrupted, match=r"kept \d of 10 samples in .*run the "
                                                  "same command again to resume"):
        run_uncertainty(camp, out, runner, progress=False)
    monkeypatch.setattr(mc, "_evaluate", real)
    assert not (out / "uncertainty.json").exists()
    rep = json.loads(run_uncertainty(camp, out, runner, progress=False).read_text())
    assert 0 < rep["resumed"] < 10
    assert _samples(out) == _samples(whole)
    # finished: the same call again computes nothing, in process or on the pool
    for workers in (0, 2):
        rep = json.loads(run_uncertainty(camp, out, runner, progress=False,
                                         workers=workers).read_text())
        assert rep["resumed"] == 10 and _samples(out) == _samples(whole)

    # more samples, the same seed: the first ten are kept, the rest computed
    more = dataclasses.replace(camp, uncertainty={**camp.uncertainty, "samples": 14})
    rep = json.loads(run_uncertainty(more, out, runner, progress=False).read_text())
    assert rep["resumed"] == 10 and rep["samples"] == 14
    # rows run sample by sample within each line: the first ten of every line are equal
    ten = np.array(_samples(whole)).reshape(-1, 10)
    assert np.array_equal(np.array(_samples(out)).reshape(-1, 14)[:, :10], ten)

    # a part that is not ours (garbage) is named on stderr and its samples run again
    parts = sorted(Path(rep["kept_in"]).glob("part-*.npz"))
    parts[0].write_bytes(b"not an archive")
    capsys.readouterr()
    rep = json.loads(run_uncertainty(camp, out, runner, progress=False).read_text())
    assert "ignoring kept samples" in capsys.readouterr().err
    assert rep["resumed"] < 10 and _samples(out) == _samples(whole)


def test_status_drivers_rank_the_input_that_sets_the_flag():
    """A flag set exactly where one input passes a threshold: that input first, with a
    rank correlation near the point-biserial of a threshold at 40 % (about 0.85), an
    independent input near 0; no flag or every flag set ranks nothing."""
    from orchestrator.campaign.mcresults import _drivers

    rng = np.random.default_rng(4)
    a, b = rng.uniform(size=2000), rng.uniform(size=2000)
    status = np.zeros((2000, 2), int)
    status[:, 0] = np.where(a < 0.4, 2, 0)         # unstable below 0.4 in "off"
    status[:, 1] = 1                               # every sample limited in "on"
    d = _drivers(status, ["off", "on"], {"b": b, "z": a})
    assert list(d["unstable"]) == ["off"] and list(d["unstable"]["off"]) == ["z", "b"]
    # ranks of a against a 0/1 flag at 40 %: -sqrt(3 p (1 - p)) = -0.849 for p = 0.4
    assert d["unstable"]["off"]["z"] == pytest.approx(-np.sqrt(3 * 0.4 * 0.6), abs=0.02)
    assert abs(d["unstable"]["off"]["b"]) < 0.1
    assert d["limit_reached"] == {}
    # uncertainty.json sorts its keys by name: the report ranks by magnitude again
    from orchestrator.report_sweeps import strongest
    back = json.loads(json.dumps(d["unstable"]["off"], sort_keys=True))
    assert list(back) == ["b", "z"] and strongest(back, 1) == ["z"]


def test_a_value_every_sample_shares_has_a_zero_width_interval():
    """A line no event excites (every sample 0) or one value for all: every resample
    gives it, so it is converged (a relative width of 0, not the 0/0 of a zero value),
    and a run that extends itself until converged does not wait on it."""
    for value in (0.0, 3.5):
        q = statistics(np.full(50, value), [0.95])["quantiles"][0.95]
        assert q["value"] == value and q["rel_width"] == 0.0 and q["converged"]
        assert q["samples_for_2pct"] == 50


def test_first_order_index_sees_a_resonance_that_a_rank_correlation_misses():
    """A mode whose frequency range straddles a disturbance line: the budget peaks in the
    middle of the input's range.  Its rank correlation is about 0, its first-order index
    near 1 (all but the within-bin spread of 25 bins and the small independent part),
    and an input that does not matter is about 0 (its scatter at 2000 samples is about
    0.004: sqrt(2 (bins - 1)) / n)."""
    from orchestrator.analysis.uncertainty import first_order_index, rank_correlation
    rng = np.random.default_rng(3)
    f, other = rng.uniform(0.95, 1.05, 2000), rng.uniform(0.5, 2.0, 2000)
    budget = 1.0 / np.hypot(1.0 - f**2, 0.01) + 0.05 * rng.standard_normal(2000)
    assert abs(rank_correlation(f, budget)) < 0.1
    assert first_order_index(f, budget) > 0.9
    assert abs(first_order_index(other, budget)) < 0.02
    st = statistics(budget, [0.95], inputs={"frequency": f, "damping": other})
    assert next(iter(st["first_order"])) == "frequency"
    assert st["first_order"]["frequency"] > 0.9 and abs(st["sensitivity"]["frequency"]) < 0.1


def test_first_order_index_of_a_sum_against_its_quadrature():
    """y = u1 + u2, u uniform on [0, 1]: the ranks of y are F(y), F the triangular CDF,
    and the index of u1 is Var(E[F(u1 + u2) | u1]) / Var(F) = 12 Var_u1(int_0^1 F(u1 + t)
    dt), computed here by quadrature; the same for u2; an infinite sample is a rank like
    another (the largest)."""
    from orchestrator.analysis.uncertainty import first_order_index

    def F(y):
        y = np.clip(y, 0.0, 2.0)
        return np.where(y < 1.0, y**2 / 2, 1.0 - (2.0 - y) ** 2 / 2)

    t = (np.arange(4000) + 0.5) / 4000
    cond = F(t[:, None] + t[None, :]).mean(axis=1)          # E[F(u1 + u2) | u1 = t]
    want = 12.0 * cond.var()
    rng = np.random.default_rng(11)
    u = rng.uniform(size=(2, 8000))
    y = u.sum(axis=0)
    # the estimate scatters by about 0.01 at 8000 samples and loses about 1/bins^2 of the
    # explained part to the spread within its 25 bins
    for k in (0, 1):
        assert first_order_index(u[k], y) == pytest.approx(want, abs=0.02)
    y[np.argmax(y)] = np.inf
    assert first_order_index(u[0], y) == pytest.approx(want, abs=0.02)
    assert 0.95 < 2 * want < 1.0     # each explains half: the ranks of a sum are nearly additive


@pytest.mark.slow
def test_the_spread_split_of_docs_mc_spread(tmp_path, truss_fmus):
    """docs/mc_spread.py: with a gain and an amplitude uncertain, the amplitudes-only
    column is the amplitude factor's own interval (one event: its modal part held at the
    median, times the factor; the bootstrap is scale-free), the modes-only column is
    the width of the samples with the factor divided out; an event without an
    amplitude-drawn source is one sentence."""
    import importlib.util

    from orchestrator.campaign.spec import parse_spec
    root = Path(__file__).resolve().parents[2]
    spec = importlib.util.spec_from_file_location("mc_spread", root / "docs" / "mc_spread.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    unc = _amp_and_gain(60, 2, 0.7, 1.3)
    data = _campaign(unc)
    camp, rep = _run(tmp_path, data, truss_fmus)
    runner = LinearRunner(camp.scenario_dir, fmu_dir=truss_fmus)
    got = mod.split(camp, parse_spec(data).events, tmp_path, runner)
    from orchestrator.analysis.uncertainty import draw
    a = draw(camp.uncertainty["parameters"], 60, 2).scalar_inputs()["amp"]
    own = statistics(a, [0.95], seed=2)["quantiles"][0.95]["rel_width"]
    assert got["samples"] == 60 and len(got["lines"]) == 4
    for label, w in got["lines"].items():
        assert w["amplitudes"] == pytest.approx(own, rel=1e-9)
        assert w["modes"] > 0          # the gain moves the loop
        line = next(ln for ln in rep["lines"] if label.startswith(
            f"{ln['instrument']} {ln['axis']} {ln['metric']}"))
        assert w["all"] == pytest.approx(line["quantiles"]["0.95"]["rel_width"], rel=1e-12)
    data["uncertainty"]["parameters"] = data["uncertainty"]["parameters"][1:]
    with pytest.raises(ValueError, match="has 0 amplitude-drawn sources"):
        mod.split(campaign_from_dict(data), parse_spec(data).events, tmp_path, runner)


# ------------------------------------------------- the [uncertainty] table in a file of its own
def _docs_uncertainty_block() -> str:
    text = (Path(__file__).resolve().parents[2] / "docs" / "linear_engine.md").read_text(
        encoding="utf-8")
    import re
    blocks = [b for b in re.findall(r"```toml\n(.*?)```", text, re.S)
              if b.startswith("[uncertainty]")]
    assert len(blocks) == 1
    return blocks[0]


def test_the_documented_and_shipped_uncertainty_tables_parse_against_the_eos_budget(
        tmp_path):
    """The docs' example (every kind and distribution) and the shipped EOS file are valid
    TOML and pass the checks against the EOS budget's instances: a user pastes them."""
    from orchestrator.campaign import load_campaign

    root = Path(__file__).resolve().parents[2] / "campaigns"
    path = tmp_path / "u.toml"
    path.write_text(_docs_uncertainty_block(), encoding="utf-8")
    camp = load_campaign(root / "eos_budget.toml", path)
    kinds = {p.kind for p in camp.uncertainty["parameters"]}
    assert kinds == {"modal_frequency", "modal_damping", "amplitude", "phase", "frequency",
                     "gain"}
    assert camp.uncertainty["samples"] == 200
    shipped = load_campaign(root / "eos_budget.toml", root / "eos_uncertainty.toml")
    u = shipped.uncertainty
    assert (u["samples"], u["seed"]) == (1000, 1)
    amp = next(p for p in u["parameters"] if p.kind == "amplitude")
    assert amp.instances == tuple(sorted(   # "all": every disturbance source of the budget
        k for k in shipped.cases[0].scenario["fmus"] if k.startswith("dist_")))
    assert "eos_uncertainty.toml" in shipped.source
    assert load_campaign(root / "eos_budget.toml", root / "eos_uncertainty.toml",
                         40).uncertainty["samples"] == 40


@pytest.mark.parametrize("content, samples, words", [
    ("[campaign]\nname = 'x'\n", None, r"holds 'campaign' and no \[uncertainty\] table; "
                                        r"expected one \[uncertainty\] table"),
    ("", None, "holds nothing"),
    ("[uncertainty]\nsamples = 3\n[events]\n", None, r"holds 'events' besides"),
    ("[uncertainty]\nsamples = 0\n", None, r"with the \[uncertainty\] of .*samples is 0"),
    ("[uncertainty]\nparameters = [{kind = 'gain', instances = ['nope']}]\n", None,
     "instances is"),
    (None, 0, "the sample count is 0"),
    (None, 5, r"has no \[uncertainty\] table, so a sample count has nothing to count"),
])
def test_a_bad_uncertainty_file_or_count_is_one_sentence(tmp_path, content, samples, words):
    from orchestrator.campaign import load_campaign

    root = Path(__file__).resolve().parents[2] / "campaigns"
    unc = None
    if content is not None:
        unc = tmp_path / "u.toml"
        unc.write_text(content, encoding="utf-8")
    with pytest.raises(CampaignError, match=words) as info:
        load_campaign(root / "eos_budget.toml", unc, samples)
    assert "\n" not in str(info.value)


@pytest.mark.slow
def test_cli_uncertainty_file_and_sample_count_equal_the_table_in_the_campaign(
        tmp_path, truss_fmus, capsys):
    """`jitterfmu campaign C --uncertainty U --samples 6` gives the samples of a campaign
    file holding U's table with samples = 6, to the last bit; a larger --samples in the
    same folder keeps those six."""
    import tomli_w

    from orchestrator.cli import main as cli_main

    unc = _amp_and_gain(50, 4, 0.5, 1.5)
    plain = _campaign(None)
    del plain["uncertainty"]
    (tmp_path / "c.toml").write_text(tomli_w.dumps(plain))
    (tmp_path / "u.toml").write_text(tomli_w.dumps({"uncertainty": unc}))
    argv = ["campaign", str(tmp_path / "c.toml"), "--uncertainty", str(tmp_path / "u.toml"),
            "--out", str(tmp_path / "cli"), "--workers", "0", "--verify", "0", "--quiet",
            "--fmu-dir", str(truss_fmus)]
    assert cli_main(argv + ["--samples", "6"]) == 0
    out = capsys.readouterr().out
    assert "uncertainty: 6 samples" in out
    # which loop the samples ran on, and why (the truss's coupling does not pay)
    assert ("\n  on: dense loop (the coupling of 'structure' with the rest of the loop is "
            "not low rank") in out and "poles by dense eigenvalues" in out
    _run(tmp_path / "inline", _campaign({**unc, "samples": 6}), truss_fmus)
    assert _samples(tmp_path / "cli") == _samples(tmp_path / "inline")
    assert cli_main(argv + ["--samples", "8"]) == 0
    assert "8 samples" in capsys.readouterr().out
    rep = json.loads((tmp_path / "cli" / "uncertainty.json").read_text())
    assert rep["resumed"] == 6


def test_convergence_hint_names_per_level_the_count_and_the_time_at_the_runs_rate():
    """The largest count over the finite, unconverged values of each level; the time of
    the samples beyond the run's at its wall time over the samples it computed (not the
    resumed ones); nothing when every finite value is converged."""
    from orchestrator.campaign.mcresults import convergence_hint

    def q(value, converged, k):
        return {"value": value, "converged": converged, "samples_for_2pct": k}

    lines = [{"quantiles": {"0.95": q(1.0, False, 4000), "0.9973": q(2.0, False, 9000)}},
             {"quantiles": {"0.95": q(1.5, False, 2500), "0.9973": q(math.inf, False, None)}},
             {"quantiles": {"0.95": q(1.2, True, None), "0.9973": q(2.1, False, 30000)}}]
    rep = {"samples": 1000, "resumed": 600, "wall_s": 80.0, "lines": lines}   # 0.2 s a sample
    text = convergence_hint(rep)
    assert "P95 about 4,000 samples, 10 min more" in text          # 3000 x 0.2 s
    assert "P99.73 about 30,000 samples, 97 min more" in text      # 29000 x 0.2 s
    assert text.index("P95") < text.index("P99.73") and "keeps these 1000" in text
    assert "\n" not in text
    done = [{"quantiles": {"0.95": q(1.0, True, None), "0.9973": q(math.inf, False, None)}}]
    assert convergence_hint({**rep, "lines": done}) is None
    # a run that computed nothing (all resumed) gives the counts without a time
    text = convergence_hint({**rep, "resumed": 1000})
    assert "P95 about 4,000 samples" in text and "more" not in text.split(";")[0]
    # the levels whose distribution-free bounds already hold are named (P95 from 59
    # samples at 95 % assurance; P99.73 needs 1109)
    for line in lines:
        line["quantiles"]["0.95"]["upper_rank"] = 962
        line["quantiles"]["0.9973"]["upper_rank"] = None
    text = convergence_hint({**rep, "assurance": 0.95})
    assert text.endswith("the upper bounds at 95 % assurance hold at this count (P95)")




def _eos_short(events, stop, uncertainty):
    """The EOS budget's cases of ``events``, isolation off, ``stop`` s long, with an
    ``[uncertainty]`` (parsed items)."""
    import dataclasses
    from orchestrator.campaign import load_campaign
    from orchestrator.experiments import eos

    camp = load_campaign(eos.CAMPAIGN)
    cases = []
    for c in camp.cases:
        if c.event in events and c.configuration == "isolation off":
            sc = json.loads(json.dumps(c.scenario))
            sc["experiment"]["stop"] = stop
            cases.append(dataclasses.replace(c, scenario=sc, key=c.key + "-short"))
    return dataclasses.replace(camp, cases=tuple(cases), engine="linear", verify=0,
                               uncertainty={"max_samples": None, **uncertainty})


@pytest.fixture(scope="module")
def eos_fmu_dir(suite_fmu_dir):
    from orchestrator.experiments import eos
    return eos.ensure_fmus(suite_fmu_dir)


@pytest.mark.long   # make test-full: co-simulated EOS samples, 31 s
@pytest.mark.slow
def test_frequency_draws_co_simulated_equal_the_linear_ones_and_move_the_lines(
        tmp_path, eos_fmu_dir):
    """kind = "frequency": a factor on the SWIR cryocooler's lines and on the MOPITT scan
    (its period), drawn per source.  The co-simulation of every sample (the FMUs with
    frequency_scale set, through the master) equals the linear engine's samples, and
    the draws change the budget (the factor is not lost on the way)."""
    import pyarrow.parquet as pq
    from orchestrator.analysis.uncertainty import Uncertain

    items = (Uncertain("f", "frequency", Distribution("uniform", 0.9, 1.1),
                       instances=("dist_swir", "dist_mopitt")),)
    got = {}
    for engine in ("linear", "cosim"):
        camp = _eos_short(("SWIR cryocooler", "MOPITT scan"), 3.0, {
            "samples": 3, "seed": 2, "confidence": (0.5,), "parameters": items,
            "engine": engine})
        runner = LinearRunner(camp.scenario_dir, fmu_dir=eos_fmu_dir)
        run_campaign(camp, tmp_path / engine, runner, progress=False)
        run_uncertainty(camp, tmp_path / engine, runner, progress=False)
        got[engine] = pq.read_table(tmp_path / engine / "uncertainty_samples.parquet"
                                    ).to_pylist()
    np.testing.assert_allclose([r["value"] for r in got["cosim"]],
                               [r["value"] for r in got["linear"]], rtol=1e-9)

    def swir_yaw(r):
        return (r["instrument"], r["axis"], r["metric"], r["window"]) == (
            "SWIR", "yaw", "peak_to_peak", 1.8)

    swir = np.array([r["value"] for r in got["linear"] if swir_yaw(r)])
    nominal = [r["value"] for r in pq.read_table(tmp_path / "linear" / "summary.parquet"
                                                 ).to_pylist()
               if swir_yaw(r) and r["event"] == RSS_EVENT]
    # three draws of the line frequencies, three different budgets, none the nominal
    assert swir.size == 3 and np.unique(np.round(swir, 12)).size == 3
    assert len(nominal) == 1 and not np.isclose(swir, nominal[0], rtol=1e-4).any()


@pytest.mark.slow
def test_a_frequency_draw_a_source_refuses_is_one_sentence_before_any_sample(
        tmp_path, eos_fmu_dir):
    """The MOPITT scan at up to 100 times its rate would turn around longer than it
    sweeps: refused, naming the draw, source and event, and no sample is run."""
    from orchestrator.analysis.uncertainty import Uncertain

    items = (Uncertain("f", "frequency", Distribution("uniform", 1.0, 100.0),
                       instances=("dist_mopitt",)),)
    camp = _eos_short(("MOPITT scan",), 1.0, {"samples": 4, "seed": 1, "confidence": (0.5,),
                                              "parameters": items, "engine": "linear"})
    runner = LinearRunner(camp.scenario_dir, fmu_dir=eos_fmu_dir)
    with pytest.raises(CampaignError, match=r"uncertain 'f' draws frequency_scale [0-9.]+ "
                       r"for dist_mopitt in event 'MOPITT scan', which it refuses: scan "
                       r"mirror source: turnaround must be shorter"):
        run_uncertainty(camp, tmp_path, runner, progress=False)
    assert not list(tmp_path.rglob("part-*.npz"))


@pytest.mark.slow
@pytest.mark.parametrize("kind, engine, sets", [("phase", "linear", "seed"),
                                               ("frequency", "linear", "frequency_scale"),
                                               ("amplitude", "cosim", "scale")])
def test_a_draw_on_an_instance_without_its_parameter_is_one_sentence(
        tmp_path, truss_fmus, kind, engine, sets):
    """The truss's excitation FMU has no seed, frequency_scale or scale: a phase or
    frequency draw on it would change nothing (the linear engine reads those from the
    source's parameters), a co-simulated amplitude would fail case by case.  Refused
    before any sample, naming the parameter and what the FMU has."""
    dist = {} if kind == "phase" else {"distribution": "uniform", "low": 0.9, "high": 1.1}
    unc = {"samples": 2, "seed": 1, "confidence": [0.5], "engine": engine,
           "parameters": [{"name": "u", "kind": kind, "instances": ["excitation"], **dist}]}
    camp = campaign_from_dict(_campaign(unc))
    runner = LinearRunner(camp.scenario_dir, fmu_dir=truss_fmus)
    with pytest.raises(CampaignError, match=rf"uncertain 'u' \({kind}\) sets {sets} of "
                       r"excitation, whose FMU 'excitation' has no such parameter \(it has "
                       r"amp1, freq1, .*\); name instances of disturbance FMUs"):
        run_uncertainty(camp, tmp_path, runner, progress=False)
    assert not list(tmp_path.rglob("part-*.npz"))
    assert not (tmp_path / "uncertainty_cases").exists()


def test_each_sample_perturbs_the_modes_by_its_own_draw():
    """The perturbed model of a Monte Carlo sample, checked against its draw: every mode's
    natural frequency and damping ratio, read from the eigenvalues of its block of the
    state matrix (Eq. 9; ``|lambda| = omega``, ``-Re lambda / |lambda| = zeta``), are the
    nominal ones times the factors drawn for that mode (per mode for the frequency, one
    factor for the band for the damping); the modes outside the band keep their damping."""
    from orchestrator.analysis.uncertainty import Uncertain
    from orchestrator.campaign.mcloop import perturbed as _perturbed
    from structfmu.models import truss10
    from structfmu.statespace import first_order

    model = truss10.reduced()
    f0 = model.omega / (2 * np.pi)
    zeta0 = model.modal_damping / (2 * model.omega)
    items = (Uncertain("f", "modal_frequency", Distribution("uniform", 0.9, 1.1),
                       per_mode=True),
             Uncertain("z", "modal_damping", Distribution("uniform", 0.5, 2.0),
                       band=(9.0, 1e4)))
    d = draw(items, 5, 7, f0)
    in_band = f0 >= 9.0
    assert 0 < in_band.sum() < model.n_modes   # the band splits the modes
    n = model.n_modes + model.n_ritz
    for s in range(d.n):
        A = first_order(_perturbed(model, d, items, s))[0]
        for i in range(model.n_modes):
            lam = np.linalg.eigvals(A[np.ix_([i, n + i], [i, n + i])])[0]
            f_want = f0[i] * d.values["f"][s, i]
            z_want = zeta0[i] * (d.values["z"][s, 0] if in_band[i] else 1.0)
            np.testing.assert_allclose(abs(lam) / (2 * np.pi), f_want, rtol=1e-12)
            np.testing.assert_allclose(-lam.real / abs(lam), z_want, rtol=1e-9)
