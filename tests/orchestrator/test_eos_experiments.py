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

pytestmark = [pytest.mark.slow, pytest.mark.paper]


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


def _dominant(table):
    """Per (instrument, axis) of the budget table: the event with the largest share of
    the RSS² in the configuration of larger RSS (the report's rule), computed here from
    the events' values."""
    out = {}
    for r in table:
        rss = {key: sum(v * v for v in r[key].values()) for key in ("events_off", "events_on")}
        worst = max(rss, key=rss.get)
        out[(r["instrument"], r["axis"])] = max(r[worst], key=lambda e: r[worst][e] ** 2)
    return out


def _check_report_opens_with_the_verdict(html, shot_dir, table):
    """The budget report: its first table is the verdict, one row per instrument axis (15)
    all in the first 1280x900 screen of headless Chromium (screenshot in shot_dir); each
    axis is named by the time history of its dominant event, in exactly one (axes and
    instruments sharing an event share its figure), the SAD dominating pitch; and the
    roll-pitch image plane is drawn."""
    import html as html_
    import re

    from .browser import ink, render, verdict_bands

    text = html.read_text(encoding="utf-8")
    first = re.search(r'<table class="(\w*)">.*?<tbody>(.*?)</tbody>', text)
    assert first.group(1) == "verdict" and first.group(2).count("<tr>") == 15
    dominant = _dominant(table)
    named = {}
    for caption in re.findall(r"<figcaption>Time history of (.*?)</figcaption>", text):
        event, _, axes = html_.unescape(caption).partition(", the dominant event of ")
        for ia in axes.split(", "):
            inst, axis = ia.split(" ")
            assert (inst, axis) not in named
            named[(inst, axis)] = event
    assert named == dominant
    # the printed table names the same event (eos-budget-table.txt, reproduce's output)
    assert {(r["instrument"], r["axis"]): r["dominant"] for r in table} == dominant
    for inst in ("CERES", "TIR", "MISR", "SWIR", "VNIR"):
        assert dominant[(inst, "pitch")] == "SAD"
    assert "boresight roll–pitch over the worst 1.8 s window" in text
    dom, png = render(html, shot_dir)
    assert dom.index('<table class="verdict">') == dom.index("<table")
    assert ink(png) > 0.05 and verdict_bands(png) == 15


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
    html = write_report(camp_dir, "html")
    _check_report_opens_with_the_verdict(html, tmp_path / "browser", table)
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
    # what it prints says so, not a wall time of cases it did not run
    assert (f"cases: {res['n_cases']} (0 failed; all {res['n_cases']} reused from an earlier "
            "run, none run now)") in eos_budget.summary(res2)
    assert f"{res['n_cases']} run now, wall per case" in eos_budget.summary(res)
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
def swir_events(tmp_path_factory, suite_fmu_dir):
    """The full-length budget's events on SWIR, isolation off, each on its worst axis
    (arcsec), largest first."""
    res = eos_budget.run(tmp_path_factory.mktemp("budget_full"), quick=False,
                         fmu_dir=suite_fmu_dir)
    assert res["n_failed"] == 0 and len(res["events"]) == 12
    worst = {}
    for r in res["budget"]:
        if r["instrument"] == "SWIR":
            for event, v in r["events_off"].items():
                worst[event] = max(worst.get(event, 0.0), v)
    return dict(sorted(worst.items(), key=lambda kv: kv[1], reverse=True))


#: The largest events on SWIR with the shipped ACS (the 0.5 Hz array mode damped through
#: roll, docs/robustness.md), arcsec, measured with ``jitterfmu reproduce eos-budget``:
#: CERES scan 1.78, SAD 1.56, SWIR cryocooler 1.30, VNIR pointing 1.14; MOPITT scan
#: fifth, 1.02.  With the earlier ACS that notched the array mode out of roll the CERES
#: scan rang it (4.58) and MOPITT scan ranked second (1.72), VNIR pointing fifth (0.71).


def test_eos_budget_swir_cryocooler_is_a_primary_contributor(swir_events):
    """Calibration check, not a reproduction: the SWIR cryocooler's amplitude (4 N) is
    fitted to the paper's primary contributors (Fig. 8: VNIR pointing, the SWIR
    cryocooler, the CERES scan and the SAD), read as one of the four largest of the
    twelve events on SWIR, each on its worst axis (distfmu.presets)."""
    assert "SWIR cryocooler" in list(swir_events)[:4]


def test_eos_budget_swir_cryocooler_needs_4n(swir_events):
    # 3 N would rank fifth: the fitted amplitude is the smallest that ranks it fourth
    top = list(swir_events)
    assert 0.75 * swir_events["SWIR cryocooler"] < swir_events[top[4]]


def test_reproduces_fig8_primary_contributors(swir_events):
    # paper (Fig. 8): the primary contributors on SWIR are VNIR pointing, the SWIR
    # cryocooler, the CERES scan and the SAD (not fitted: only the cryocooler's
    # amplitude is)
    assert set(list(swir_events)[:4]) == {"VNIR pointing", "SWIR cryocooler", "CERES scan",
                                          "SAD"}


@pytest.fixture(scope="module")
def testbed(out, suite_fmu_dir):
    return run_experiment("testbed-isolation", out, quick=True, fmu_dir=suite_fmu_dir)


def test_testbed_isolation(testbed, out):
    res = testbed
    red, lin = res["jitter_reduction_pct"], res["linear_reduction_pct"]
    assert set(red) == {"mount3", "all_mounts"}
    # every configuration: stable with >= 6 dB gain margin (linear model, all active
    # loops scaled together and each alone); strut voltages inside +-50 V
    assert min(res["gain_margin_db"].values()) >= 6.0
    assert 0.0 < res["max_voltage_v"] < 50.0
    # the layout (docs/eos_testbed.md): the paper removed about 80 % with mount #3 alone
    # and up to 80 % in its tests, so a model of the testbed must let these struts remove
    # at least that (paper: a lower bound on the upper bound); holding the payload
    # accelerometers at zero is one set of strut commands, so it cannot beat the bound
    assert res["upper_bound_pct"]["mount3"] >= 80.0
    assert res["upper_bound_pct"]["all_mounts"] >= 80.0
    for k in ("mount3", "all_mounts"):
        assert res["accel_null_pct"][k] <= res["upper_bound_pct"][k] + 1e-6
    # the bounds are listed true upper bound first, each saying what it bounds
    assert res["bounds"][0]["name"] == "upper bound" and res["bounds"][0]["is_bound"]
    assert res["bounds"][0]["pct"] == res["upper_bound_pct"]
    assert not res["bounds"][1]["is_bound"]
    # no controller beats the least-squares upper bound
    for k in ("mount3", "all_mounts"):
        assert lin[k] <= res["upper_bound_pct"][k] + 1e-6
    # robust: the shipped gains keep 6 dB over the testbed's uncertainty (frequencies
    # x0.95-1.05, damping x0.5-2) at its nine corners (testbed_robust; the factors were
    # set on 40 more per-mode points), and they are the nominal design scaled down
    rob = res["robust"]
    for k in ("mount3", "all_mounts"):
        assert rob[k]["margin_db"] >= 6.0
        assert rob["nominal_gains_linear_reduction_pct"][k] > lin[k]
    # the explanation of the nominal design's number: at 6 dB on the nominal plant it
    # removes what the law's bus path removes as a pure feedforward with the best real gain
    assert rob["nominal_gains_linear_reduction_pct"]["mount3"] == pytest.approx(
        res["feedforward_best_gain_mount3_pct"], abs=2.0)
    # the margin is set by a pole that leaves the unit circle (a real instability)
    assert res["margin_limiting_poles"]["mount3"][0]["abs_z"] >= 1.0
    # a settled before-window (docs/eos_experiments.md): with isolation off the boresight
    # RMS changes by at most 2 % between the windows (the experiment moves the switch-on
    # later until it does), the windows are where the JSON says, and each isolated run
    # has settled in its after-window too (its own change over the last two windows)
    assert abs(res["off_change_pct"]) <= res["settled_pct"] == 2.0
    assert res["t_on_s"] >= 8.4 and res["windows_s"]["before"] == pytest.approx(
        [res["t_on_s"] - 1.2, res["t_on_s"]])
    assert res["windows_s"]["after"][0] >= res["t_on_s"] + 2.0
    assert all(abs(c) <= 2.0 for c in res["after_change_pct"].values())
    # on settled windows the co-simulation is the linear design's steady state (an
    # independent computation: the closed loop's frequency response at the three
    # harmonics), both ways: two runs and the paper's before/after in one run
    for k in ("mount3", "all_mounts"):
        assert red[k] == pytest.approx(lin[k], abs=1.0)
        assert res["paper_way_reduction_pct"][k] == pytest.approx(lin[k], abs=1.0)
    # the instruments (testbed_instruments): the simulated jitter is below half a step
    # of the optical scoring system (0.2 arcsec), so at this level it reads only its own
    # quantisation; scaled to 1 arcsec (a linear system) it reads the reductions to a
    # point.  The stacks' servo loop (assumed 100 Hz) lags the law: with the same gains
    # it removes less at less margin (docs/eos_experiments.md gives the numbers)
    inst = res["instruments"]
    assert res["boresight_rms"]["off"]["before_arcsec_rms"] < 0.1
    assert inst["oss_at_level"]["off_before_arcsec"] == pytest.approx(1.0, abs=0.05)
    for k in ("mount3", "all_mounts"):
        assert inst["oss_at_level"][k]["paper_way_pct"] == pytest.approx(
            res["paper_way_reduction_pct"][k], abs=1.0)
    assert inst["servo"]["reduction_pct"] < inst["analog_no_servo"]["reduction_pct"]
    assert inst["servo"]["gain_margin_db"] < inst["analog_no_servo"]["gain_margin_db"]
    # the servo changes the plant the law sees, not what the struts can do
    assert inst["servo"]["upper_bound_pct"] == pytest.approx(res["upper_bound_pct"]["mount3"],
                                                             abs=0.1)
    assert (out / "testbed-isolation.png").is_file()


def test_testbed_regression_pin(testbed):
    """A regression pin, not a reproduction: today's linear design values (step-mean
    coupling, the shipped robust gains; the nominal 6 dB design's beside them), to 0.5
    points (frequency responses of a fixed loop, well conditioned); a change of the model
    or the gains moves them."""
    lin = testbed["linear_reduction_pct"]
    assert lin["mount3"] == pytest.approx(16.4, abs=0.5)
    assert lin["all_mounts"] == pytest.approx(17.0, abs=0.5)
    nominal = testbed["robust"]["nominal_gains_linear_reduction_pct"]
    assert nominal["mount3"] == pytest.approx(46.8, abs=0.5)
    assert nominal["all_mounts"] == pytest.approx(48.3, abs=0.5)


#: Why the testbed misses (measured with ``jitterfmu reproduce testbed-isolation``, settled
#: windows): with gains that keep 6 dB over the testbed's uncertainty the stated law
#: removes 16.9 % from mount #3 and 17.5 % with all three the paper's way (quick run),
#: 16.4 / 17.0 % on the linear model, against an upper bound of 82.2 % at mount #3; at
#: 6 dB on the nominal plant alone 46.8 / 48.3 % (unstable over the set); the paper's
#: structure with corners and gains free reaches 78.6 % at 6 dB on the nominal plant
#: (docs/eos_experiments.md).
TESTBED_MISS = ("on the stiff struts the stated law at 6 dB over the testbed's uncertainty "
                "(modal frequencies x0.95-1.05, damping x0.5-2) removes 17 % from mount #3 "
                "and 17 % with all three on a settled response (upper bound 82 %); the "
                "damping uncertainty of the 0.5 %-damped bus modes is what stops it "
                "(docs/eos_experiments.md)")


def _paper_way(res, k):
    """The before/after reduction (%) recomputed from the JSON's boresight RMS (arcsec)."""
    b = res["boresight_rms"][k]
    return 100.0 * (1.0 - b["after_arcsec_rms"] / b["before_arcsec_rms"])


@pytest.mark.xfail(strict=True, reason=TESTBED_MISS)
def test_reproduces_fig15_mount3(testbed):
    # paper: about 80 % with mount #3 alone, read the paper's way (before and after the
    # switch-on in one run, on a settled response); "about" is +-5 points
    # (verdicts.ABOUT_PCT)
    v = testbed["verdicts"][0]
    assert v["target"].startswith("Fig. 15") and v["band"] == [75.0, 85.0]
    assert v["ours"] == pytest.approx(_paper_way(testbed, "mount3"), rel=1e-9)
    assert v["reproduced"] is True


@pytest.mark.xfail(strict=True, reason=TESTBED_MISS)
def test_reproduces_tests_overall_all_mounts(testbed):
    # paper: "Payload isolation tests have confirmed 50 to 80 percent reduction", read
    # the paper's way on a settled response
    v = testbed["verdicts"][1]
    assert v["band"] == [50.0, 80.0]
    assert v["ours"] == pytest.approx(_paper_way(testbed, "all_mounts"), rel=1e-9)
    assert 50.0 <= v["ours"] <= 80.0 and v["reproduced"] is True


@pytest.mark.xfail(strict=True, reason="the isolation band of mount #3 ends at 30 Hz, not "
                   "about 45 Hz (docs/eos_experiments.md)")
def test_reproduces_fig13_bandwidth(testbed):
    assert testbed["verdicts"][2]["reproduced"] is True


@pytest.fixture(scope="module")
def testbed_hybrid(out, suite_fmu_dir):
    from orchestrator.experiments import testbed_isolation

    # the full run: its after-window ends 7.2 s after the switch-on
    return testbed_isolation.run(out, quick=False, fmu_dir=suite_fmu_dir, variant="hybrid")


def test_testbed_isolation_hybrid(testbed_hybrid, out):
    # mount #3 a hybrid isolator (stack + elastomer, eos_testbed.build(iso3="hybrid")).
    # Its elastomer was calibrated to give the paper's 80 % on the earlier coupling, so
    # nothing here asserts the paper's number; what was not fitted: the loops keep 6 dB,
    # the voltages stay inside +-50 V, the isolation-off run is settled between the
    # windows, the co-simulation settles where the linear model says (two runs), and no
    # result beats the least-squares bound
    res = testbed_hybrid
    red, lin = res["jitter_reduction_pct"], res["linear_reduction_pct"]
    assert res["variant"] == "hybrid"
    assert abs(res["off_change_pct"]) <= 2.0
    assert min(res["gain_margin_db"].values()) >= 6.0
    assert all(res["robust"][k]["margin_db"] >= 6.0 for k in ("mount3", "all_mounts"))
    assert 0.0 < res["max_voltage_v"] < 50.0
    for k in ("mount3", "all_mounts"):
        assert red[k] == pytest.approx(lin[k], abs=5.0)
        assert lin[k] <= res["upper_bound_pct"][k] + 1e-6
    assert all(g != 0.0 for g in res["gain"]["all_mounts"])
    assert (out / "testbed-isolation-hybrid.png").is_file()


@pytest.fixture(scope="module")
def swir(out, suite_fmu_dir):
    return run_experiment("swir-isolation", out, quick=True, fmu_dir=suite_fmu_dir)


def test_swir_isolation(swir, out):
    res = swir
    red, off = res["reduction_pct"], res["jitter_off_arcsec"]
    # paper (Fig. 9 text): VNIR pointing gives about 1 arcsec/1.8 s on all three SWIR axes
    assert all(0.5 <= off[a] <= 2.0 for a in ("roll", "pitch", "yaw"))
    # zero gains give 0 %, a flipped sign amplifies or goes unstable: both fail here
    assert red["roll"] > 0 and red["yaw"] > 0
    # the co-simulation is the linear design model (same discretisation and delays)
    for a in ("roll", "pitch", "yaw"):
        assert red[a] == pytest.approx(res["linear_reduction_pct"][a], abs=1.0)
    # all twelve loops keep >= 6 dB common gain margin
    assert res["margins"]["mimo_gain_margin_db"] >= 6.0
    # paper: the isolation mounts need < 5 um of stroke and < 15 lb of force (full scale)
    assert 0.0 < res["max_stroke_um"] < 5.0
    assert 0.0 < res["max_force_lbf"] < 15.0
    # the twelve stacks could cancel the SWIR LOS exactly (the upper bound), but not
    # within 15 lbf; the least-squares inputs within the limits are not called a bound
    assert min(res["upper_bound_pct"].values()) >= 99.0
    assert res["upper_bound_needs"]["max_force_lbf"] > 15.0
    assert [b["is_bound"] for b in res["bounds"]] == [True, False]
    assert (out / "swir-isolation.png").is_file()


def _verdict(res, target):
    return next(v for v in res["verdicts"] if v["target"] == target)


#: Why Fig. 9's roll and yaw miss in the quick run: the reduction depends on the ACS, and
#: the paper's (EOS AM-1's, in PLATSIM) is not ours.  Measured on the experiment's linear
#: model (equal to its co-simulation), quick run (jitterfmu reproduce swir-isolation
#: --quick): SWIR roll / yaw reduction 35.5 / 44.5 % with the shipped ACS (the array mode
#: damped through roll, docs/robustness.md); the full run (jitterfmu reproduce
#: swir-isolation) gives 35.5 / 53.6 %, yaw reproduced there.  With the earlier ACS that
#: notched the array mode: 16.9 / 42.1 %.
FIG9_ACS = ("with the shipped ACS (designed on the flexible plant) the leg loops remove {} "
            "of SWIR {} in the quick run, against the paper's {} (docs/eos_experiments.md)")


@pytest.mark.xfail(strict=True, reason=FIG9_ACS.format("35.5 %", "roll",
                                                       "about 30 % (25-35 %)"))
def test_reproduces_fig9_roll(swir):
    # paper: roll reduced by only 30 % (rigid-body motion): "about 30 %" is 25-35 %
    # (verdicts.ABOUT_PCT)
    roll = _verdict(swir, "SWIR roll reduction")
    assert roll["band"] == [25.0, 35.0]
    assert roll["reproduced"] is True and 25.0 <= swir["reduction_pct"]["roll"] <= 35.0


@pytest.mark.xfail(strict=True, reason=FIG9_ACS.format(
    "44.5 % (53.6 % in the full 6 s run)", "yaw",
    "at least 50 %"))
def test_reproduces_fig9_yaw(swir):
    # paper: yaw lowered "significantly" (read: at least 50 %)
    yaw = _verdict(swir, "SWIR yaw reduction")
    assert yaw["reproduced"] is True and swir["reduction_pct"]["yaw"] >= 50.0


def test_swir_isolation_regression_pin(swir):
    """A regression pin, not a reproduction: today's SWIR jitter off (arcsec) and the leg
    loops' reductions (%) in the quick run, measured with ``jitterfmu reproduce
    swir-isolation --quick`` (the shipped ACS); to 0.01 arcsec and 0.5 points (the
    co-simulation equals the linear model to 1e-9): a change of the ACS, the structure
    or the law moves them."""
    SWIR_OFF_PIN = {"roll": 1.145, "pitch": 0.599, "yaw": 0.642}
    SWIR_REDUCTION_PIN = {"roll": 35.5, "pitch": 10.3, "yaw": 44.5}
    for a in ("roll", "pitch", "yaw"):
        assert swir["jitter_off_arcsec"][a] == pytest.approx(SWIR_OFF_PIN[a], abs=0.01)
        assert swir["reduction_pct"][a] == pytest.approx(SWIR_REDUCTION_PIN[a], abs=0.5)


@pytest.mark.xfail(strict=True, reason="SWIR pitch (10 %) rides on 70-125 Hz bus modes with "
                   "5-17 % of their strain energy in the legs: one strain loop per leg makes "
                   "the legs springs and dampers, which cannot cut it (5 % damping on every "
                   "mode above 20 Hz gives 34 %); one controller on the same twelve strains "
                   "does (test_swir_isolation_central) (docs/eos_experiments.md)")
def test_reproduces_fig9_pitch(swir):
    # paper: pitch lowered significantly (read: at least 50 %)
    assert _verdict(swir, "SWIR pitch reduction")["reproduced"] is True


@pytest.mark.xfail(strict=True, reason="MISR falls 36 % (41 % in the full run) with the "
                   "twelve leg loops, more than the paper's about 10 % "
                   "(docs/eos_experiments.md; the cause is not measured yet)")
def test_reproduces_fig9_misr(swir):
    assert _verdict(swir, "MISR reduction")["reproduced"] is True


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
        # and the default run reports the same law's linear result
        assert swir["central_law_linear"]["reduction_pct"][a] == pytest.approx(
            res["linear_reduction_pct"][a], abs=1e-6)
    # the isolation-off run is the same scenario without control
    for a in ("roll", "pitch", "yaw"):
        assert res["jitter_off_arcsec"][a] == pytest.approx(swir["jitter_off_arcsec"][a],
                                                            rel=1e-9)
    # per-target verdicts: more than the paper's "about 30 %" on roll and "about 10 %" on
    # MISR is beating the paper, not missing it; every target is met or beaten
    out_of = {v["target"]: v["outcome"] for v in res["verdicts"]}
    assert out_of["SWIR roll reduction"] == "beats the paper"
    assert out_of["MISR reduction"] == "beats the paper"
    assert {out_of[t] for t in out_of if t not in ("SWIR roll reduction", "MISR reduction")} \
        == {"reproduced"}
    assert res["reproduced"] is False
    assert res["verdict"].startswith("reproduced or beaten on every target")
    # the least-squares inputs within the limits are not a bound: this law, within the
    # same limits, removes more on some axis (yaw: 52.4 % against 28.5 %; roll, 59.4 %
    # against 23.5 % with the earlier 0.1 Hz ACS, is 45.2 % against 56.5 % now)
    ls = res["least_squares_within_limits_pct"]
    assert any(red[a] > ls[a] for a in ("roll", "pitch", "yaw"))
    assert res["bounds"][1]["is_bound"] is False
    assert (out / "swir-isolation-central.png").is_file()


def test_every_reproduced_verdict_is_inside_its_band(out, testbed, testbed_hybrid, swir,
                                                     swir_central):
    """Over every experiment JSON written here (eos-budget, testbed-isolation and its
    hybrid variant, swir-isolation and its central variant): a verdict marked reproduced
    has its number inside its stated band, one inside its band is marked so, and the
    experiment's ``reproduced`` is true exactly when every verdict is
    (:func:`orchestrator.experiments.verdicts.inconsistencies`)."""
    import json

    from orchestrator.experiments import verdicts as vd

    files = sorted(out.glob("*.json"))
    assert {f.stem for f in files} >= {"testbed-isolation", "swir-isolation"}
    checked = 0
    for f in files:
        res = json.loads(f.read_text(encoding="utf-8"))
        assert vd.inconsistencies(res) == [], f.name
        checked += len(res.get("verdicts") or [])
    # the fixtures' results too (a variant run writes no JSON of its own here)
    for res in (testbed, testbed_hybrid, swir, swir_central):
        assert vd.inconsistencies(res) == []
        checked += len(res["verdicts"])
    assert checked >= 10
