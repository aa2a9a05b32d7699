"""The EOS experiments (paper: EOS AM-1 jitter simulation, payload isolation, EOS Dynamics
Testbed) in quick mode, checked against the paper where our model reproduces it and
against the physics that must hold where it does not (each JSON says which in
``reproduced`` and ``note``)."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from orchestrator.experiments import eos_budget
from orchestrator.experiments import run as run_experiment
from orchestrator.report import budget_grid, write_report

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    return tmp_path_factory.mktemp("eos")


def _requirements_by_instrument(path):
    """The campaign file's requirements, read with tomllib (independently of the code)."""
    data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    reqs = {}
    for r in data["requirements"]:
        assert "axis" not in r  # the shipped file sets one value per instrument
        assert (r["metric"], r["window"]) == ("peak_to_peak", 1.8)
        reqs[r["instrument"]] = r["value"]
    return reqs


def test_eos_budget(out, tmp_path, suite_fmu_dir):
    res = run_experiment("eos-budget", out, quick=True, fmu_dir=suite_fmu_dir)
    assert res["n_failed"] == 0
    table = res["budget"]
    # five instruments x three axes, each with a finite RSS off and on and a requirement
    assert {(r["instrument"], r["axis"]) for r in table} == {
        (i, a) for i in ("CERES", "TIR", "MISR", "SWIR", "VNIR")
        for a in ("roll", "pitch", "yaw")}
    # requirements are the campaign file's values, unchanged (no run sets them)
    shipped = _requirements_by_instrument(eos_budget.CAMPAIGN)
    assert shipped == {"CERES": 720.0, "TIR": 6.6, "MISR": 20.0, "SWIR": 2.2, "VNIR": 1.1}
    for r in table:
        assert r["requirement"] == shipped[r["instrument"]]
        assert math.isfinite(r["rss_off"]) and r["rss_off"] > 0
        assert math.isfinite(r["rss_on"]) and r["rss_on"] > 0
        # RSS over events: the root of the sum of squares of the events' values
        assert r["rss_off"] == pytest.approx(
            math.sqrt(sum(v * v for v in r["events_off"].values())), rel=1e-9)
        # margin = requirement - RSS; change = 100 (off - on) / off
        assert r["margin_off"] == pytest.approx(r["requirement"] - r["rss_off"])
        assert r["margin_on"] == pytest.approx(r["requirement"] - r["rss_on"])
        assert r["reduction_pct"] == pytest.approx(
            100 * (r["rss_off"] - r["rss_on"]) / r["rss_off"])
        # the paper's isolation result is shown where the paper gives one, and only there
        assert bool(r["paper"]) == (r["instrument"] in ("SWIR", "MISR"))
        # isolation must not make any axis materially worse (stable, small-gain loops)
        assert r["rss_on"] <= 1.05 * r["rss_off"]
    text = (out / "eos-budget-table.txt").read_text()
    assert "inputs, not derived from this run" in text and "large cut" in text

    # The report's budget chart has isolation off and on for every instrument and axis.
    camp_dir = Path(res["campaign_dir"])
    write_report(camp_dir, "html")
    summary = pq.read_table(camp_dir / "summary.parquet").to_pylist()
    rows = [r for r in summary if r["metric"] == "peak_to_peak"]
    grid = budget_grid(rows, {i: {"roll": 0, "pitch": 0, "yaw": 0} for i in shipped})
    assert [g[0] for g in grid.groups] == ["isolation off", "isolation on"]
    assert len(grid.columns) == 15 and grid.events[-1] == "RSS"
    assert np.isfinite(grid.values[:, -1, :]).all()

    # Another requirement in the campaign file changes the margins and nothing else:
    # the cases are reused (their keys do not contain requirements), so the new margin
    # can only come from the file.
    src = eos_budget.CAMPAIGN.read_text(encoding="utf-8")
    import re
    rel = re.search(r'^scenario = "(.+)"$', src, re.M).group(1)
    base = (eos_budget.CAMPAIGN.parent / rel).resolve()
    changed = src.replace(f'scenario = "{rel}"', f'scenario = "{base.as_posix()}"')
    i = changed.index('instrument = "SWIR"')
    changed = changed[:i] + changed[i:].replace("value = 2.2", "value = 5.0", 1)
    assert changed.count("value = 5.0") == 1
    mine = tmp_path / "my_budget.toml"
    mine.write_text(changed, encoding="utf-8")
    res2 = eos_budget.run(out, quick=True, fmu_dir=suite_fmu_dir, campaign=mine)
    assert res2["n_run"] == 0 and res2["n_skipped"] == res["n_cases"]
    before = {(r["instrument"], r["axis"]): r for r in table}
    for r in res2["budget"]:
        b = before[(r["instrument"], r["axis"])]
        assert r["rss_off"] == b["rss_off"] and r["rss_on"] == b["rss_on"]
        if r["instrument"] == "SWIR":
            assert r["requirement"] == 5.0
            assert r["margin_off"] == pytest.approx(5.0 - r["rss_off"])
            assert r["margin_off"] == pytest.approx(b["margin_off"] + 2.8)
        else:
            assert r["requirement"] == b["requirement"]
            assert r["margin_off"] == b["margin_off"]


@pytest.fixture(scope="module")
def testbed(out, suite_fmu_dir):
    return run_experiment("testbed-isolation", out, quick=True, fmu_dir=suite_fmu_dir)


def test_testbed_isolation(testbed, out):
    res = testbed
    red, lin = res["jitter_reduction_pct"], res["linear_reduction_pct"]
    assert set(red) == {"mount3", "all_mounts"}
    # every configuration: stable with >= 6 dB gain margin (linear model, all active
    # loops scaled together); strut voltages inside the paper's +-50 V operating range
    assert min(res["gain_margin_db"].values()) >= 6.0
    assert 0.0 < res["max_voltage_v"] < 50.0
    # the layout (docs/eos_testbed.md): mount #3 is in the dominant 22 Hz path, so an
    # ideal loop at mount #3 alone could remove about the paper's 80 %
    assert res["ideal_ceiling_pct"]["mount3"] >= 70.0
    assert res["ideal_ceiling_pct"]["all_mounts"] >= 90.0
    # the isolation attenuates the boresight jitter in the co-simulation, as designed on
    # the linear model (zero gains give 0 %, a flipped sign amplifies or goes unstable)
    # (the designed values are 22 % and 25 %, each mount with its own gain; the quick run
    # measures 2.4 s after switch-on, while the 0.5 %-damped 23 Hz bus mode still settles)
    assert lin["mount3"] >= 15.0 and red["mount3"] >= 12.0
    assert lin["all_mounts"] >= 18.0 and red["all_mounts"] >= 12.0
    # even as pure feedforward the stated compensator's bus path could not reach 70 %
    assert 0.0 < res["feedforward_bound_mount3_pct"] < 70.0
    assert red["mount3"] == pytest.approx(lin["mount3"], abs=8.0)
    assert (out / "testbed-isolation.png").is_file()


@pytest.mark.xfail(strict=True, reason="the stated law on the stiff struts is gain-limited "
                   "to about 22 % at 6 dB margin (docs/eos_experiments.md)")
def test_testbed_isolation_reaches_the_papers_attenuation(testbed):
    # paper: about 80 % with mount #3 alone, 50-80 % with all three
    red = testbed["jitter_reduction_pct"]
    assert red["mount3"] >= 70.0
    assert 50.0 <= red["all_mounts"] <= 80.0
    assert testbed["reproduced"] is True


@pytest.fixture(scope="module")
def testbed_hybrid(out, suite_fmu_dir):
    from orchestrator.experiments import testbed_isolation

    # the full 9.6 s run: the quick one measures 2.4 s after switch-on,
    # while the switch-on transient still rings (70.1 % there against 78.6 %)
    return testbed_isolation.run(out, quick=False, fmu_dir=suite_fmu_dir, variant="hybrid")


def test_testbed_isolation_hybrid_reaches_the_papers_attenuation(testbed_hybrid, out):
    # mount #3 a hybrid isolator (stack + elastomer, eos_testbed.build(iso3="hybrid")),
    # the law exactly as stated at 7 times its gains: the paper's "about 80 %" with
    # mount #3 alone and 50-80 % with all three (each mount its own gain), at >= 6 dB
    # gain margin and inside +-50 V
    res = testbed_hybrid
    red, lin = res["jitter_reduction_pct"], res["linear_reduction_pct"]
    assert res["variant"] == "hybrid"
    assert min(res["gain_margin_db"].values()) >= 6.0
    assert 0.0 < res["max_voltage_v"] < 50.0
    assert lin["mount3"] >= 80.0
    assert red["mount3"] >= 70.0
    assert res["boresight_rms"]["mount3"]["before_after_reduction_pct"] >= 70.0
    assert 50.0 <= red["all_mounts"] <= 80.0
    assert all(g != 0.0 for g in res["gain"]["all_mounts"])
    assert res["reproduced"] is True
    # no controller can beat the least-squares bound
    for k in ("mount3", "all_mounts"):
        assert lin[k] <= res["optimal_bound_pct"][k] + 1e-6
    assert (out / "testbed-isolation-hybrid.png").is_file()


@pytest.mark.xfail(strict=True, reason="the isolation bandwidth of the hybrid mount #3 is "
                   "30 Hz, not the paper's 45 (docs/eos_experiments.md)")
def test_testbed_isolation_hybrid_reaches_the_papers_bandwidth(testbed_hybrid):
    assert testbed_hybrid["isolation_bandwidth_hz"] == pytest.approx(45.0, abs=7.0)


@pytest.fixture(scope="module")
def swir(out, suite_fmu_dir):
    return run_experiment("swir-isolation", out, quick=True, fmu_dir=suite_fmu_dir)


def test_swir_isolation(swir, out):
    res = swir
    red, off = res["reduction_pct"], res["jitter_off_arcsec"]
    # paper (Fig. 9 text): VNIR pointing gives about 1 arcsec/1.8 s on all three SWIR axes
    assert all(0.5 <= off[a] <= 2.0 for a in ("roll", "pitch", "yaw"))
    # paper: roll reduced by only 30 % (rigid-body motion), yaw significantly.  Zero gains
    # give 0 %, a flipped sign amplifies or goes unstable: both fail here.
    assert 15.0 <= red["roll"] <= 45.0
    assert red["yaw"] >= 50.0
    # the co-simulation is the linear design model (same discretisation and delays)
    for a in ("roll", "pitch", "yaw"):
        assert red[a] == pytest.approx(res["linear_reduction_pct"][a], abs=1.0)
    # all twelve loops keep >= 6 dB common gain margin
    assert res["margins"]["mimo_gain_margin_db"] >= 6.0
    # paper: the isolation mounts need < 5 um of stroke and < 15 lb of force (full scale)
    assert 0.0 < res["max_stroke_um"] < 5.0
    assert 0.0 < res["max_force_lbf"] < 15.0
    # the twelve stacks could cancel the SWIR LOS exactly, but not within 15 lbf
    assert min(res["ideal_ceiling_pct"].values()) >= 99.0
    assert res["ideal_ceiling_needs"]["max_force_lbf"] > 15.0
    assert (out / "swir-isolation.png").is_file()


@pytest.mark.xfail(strict=True, reason="SWIR pitch rides on 70-125 Hz bus modes with 5-17 % "
                   "of their strain energy in the legs: one strain loop per leg makes the legs "
                   "springs and dampers, which cannot cut it (5 % damping on every mode above "
                   "20 Hz gives 34 %); one controller on the same twelve strains does "
                   "(test_swir_isolation_central); MISR falls 25 %, more than the paper's "
                   "10 % (docs/eos_experiments.md)")
def test_swir_isolation_reaches_the_papers_attenuation(swir):
    # paper: pitch and yaw lowered significantly, MISR about 10 %
    assert swir["reduction_pct"]["pitch"] >= 50.0
    assert 3.0 <= swir["misr_reduction_pct"] <= 20.0
    assert swir["reproduced"] is True


@pytest.fixture(scope="module")
def swir_central(out, suite_fmu_dir):
    return run_experiment("swir-isolation", out, quick=True, fmu_dir=suite_fmu_dir,
                          variant="central")


def test_swir_isolation_central(swir, swir_central, out):
    # one controller (LQG, central_law) on the same twelve strain gauges and stacks: the
    # paper's "significant" pitch and yaw reductions, inside its stroke and force limits,
    # with >= 6 dB of gain margin both ways (an LQG may have unstable poles of its own)
    res = swir_central
    red = res["reduction_pct"]
    assert res["variant"] == "central" and res["law"]["design"] == "central_law"
    assert red["pitch"] >= 50.0 and red["yaw"] >= 50.0
    assert res["margins"]["mimo_gain_margin_db"] >= 6.0
    assert res["margins"]["mimo_gain_reduction_margin_db"] >= 6.0
    assert 0.0 < res["max_stroke_um"] < 5.0
    assert 0.0 < res["max_force_lbf"] < 15.0
    # the co-simulation (one 12-in/12-out controller FMU) is the linear design model
    for a in ("roll", "pitch", "yaw"):
        assert red[a] == pytest.approx(res["linear_reduction_pct"][a], abs=1.0)
        # and the default run reports the same law's linear result as its bound
        assert swir["central_law_linear"]["reduction_pct"][a] == pytest.approx(
            res["linear_reduction_pct"][a], abs=1e-6)
    # the isolation-off run is the same scenario without control
    for a in ("roll", "pitch", "yaw"):
        assert res["jitter_off_arcsec"][a] == pytest.approx(swir["jitter_off_arcsec"][a],
                                                            rel=1e-9)
    assert (out / "swir-isolation-central.png").is_file()
