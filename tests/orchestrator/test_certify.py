"""The robust-stability certificate (orchestrator.analysis.certify) against the truth."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from orchestrator.analysis import linearize
from orchestrator.analysis.certify import certify
from orchestrator.analysis.certify_bounds import _rect, _ratio_min, dh_bound
from orchestrator.analysis.robust import loop_at, pole_radius, robust_stability, uncertain_set
from orchestrator.analysis.uncertainty import Distribution, Uncertain

SHIPPED = Path("scenarios/truss10_closed_loop.toml")


@pytest.fixture(scope="module")
def single_rate(suite_fmus, tmp_path_factory):
    """The ten-bay truss with its amplifiers at the laws' 250 Hz: one loop rate, so the
    certificate covers the whole loop (the scenario file's path)."""
    from orchestrator.experiments.truss_decay import FMUS

    suite_fmus(*FMUS)
    text = SHIPPED.read_text(encoding="utf-8")
    for name in ("piezo_diag", "piezo_long"):
        head = f"[fmus.{name}]\n"
        i = text.index(head)
        j = text.index("period = 1e-3\n", i)
        text = (text[:j] + "period = 4e-3\nparameters = { hold_step = 4e-3 }\n"
                + text[j + len("period = 1e-3\n"):])
    path = tmp_path_factory.mktemp("truss") / "truss_single_rate.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def lin(single_rate, suite_fmu_dir):
    return linearize(single_rate, fmu_dir=suite_fmu_dir)


def _one_mode(band, f=(0.95, 1.05), d=(0.5, 2.0)):
    return [Uncertain("freq", "modal_frequency", Distribution("uniform", *f), per_mode=True,
                      band=band),
            Uncertain("damp", "modal_damping", Distribution("uniform", *d), per_mode=True,
                      band=band)]


def test_value_set_bounds_against_brute_force():
    # the edge maximum of |1/d - 1/d0| and the edge minimum of |d - d*|/|d| over the
    # rectangle hold against dense grids of the parameters and of the rectangle
    rng = np.random.default_rng(1)
    for _ in range(200):
        w0 = rng.uniform(1, 100)
        c0 = 2 * w0 * rng.uniform(1e-3, 0.05)
        nu = w0 * rng.uniform(0.5, 1.5)
        fw, fz = (rng.uniform(0.85, 1), rng.uniform(1, 1.15)), (rng.uniform(0.2, 1),
                                                                rng.uniform(1, 3))
        W = np.linspace(w0 * fw[0], w0 * fw[1], 121)[:, None]
        Z = np.linspace(fz[0], fz[1], 121)[None, :]
        d = W ** 2 - nu ** 2 + 1j * nu * c0 * (W / w0) * Z
        d0 = w0 ** 2 - nu ** 2 + 1j * nu * c0
        assert np.abs(1 / d - 1 / d0).max() <= dh_bound(nu, w0, c0, fw, fz)
        corners = _rect(nu, w0, c0, fw, fz)
        re = np.linspace(corners[0].real, corners[1].real, 161)[:, None]
        im = np.linspace(corners[0].imag, corners[2].imag, 161)[None, :]
        dstar = d0 * rng.uniform(0.5, 2) * np.exp(1j * rng.uniform(-3, 3))
        grid = np.abs(re + 1j * im - dstar) / np.abs(re + 1j * im)
        assert _ratio_min(corners, np.asarray(dstar)) <= grid.min()


def _true_margin(lin, items, fw_span=0.1, steps=14):
    """The exact margin of a one-mode set: for each frequency factor the damping factor
    at which the loop turns unstable (bisection on eigenvalues), the scale of that point,
    minimised over the frequency factor (a coarse grid, then a fine one)."""
    uset = uncertain_set(lin, items)
    (lo_f, hi_f), (lo_d, hi_d) = uset.bounds("freq"), uset.bounds("damp")

    def unstable(fw, fz):
        return pole_radius(loop_at(lin, uset, {"freq": np.array([fw]),
                                           "damp": np.array([fz])})) >= 1.0

    def k_at(fw):
        kf = (1 - fw) / (1 - lo_f) if fw < 1 else (fw - 1) / (hi_f - 1)
        a, b = 1e-3, 1.0               # damping factor: unstable at a, stable at 1
        if not unstable(fw, a):
            return math.inf
        for _ in range(steps):
            m = 0.5 * (a + b)
            a, b = (m, b) if unstable(fw, m) else (a, m)
        return max(kf, (1 - b) / (1 - lo_d))

    coarse = np.linspace(1 - fw_span, 1 + fw_span, 41)
    ks = [k_at(f) for f in coarse]
    best = coarse[int(np.argmin(ks))]
    fine = np.linspace(best - 0.005, best + 0.005, 21)
    return min(min(ks), min(k_at(f) for f in fine))


@pytest.mark.parametrize("band,f,d", [((40, 50), (0.95, 1.05), (0.5, 2.0)),
                                      ((70, 80), (0.8, 1.2), (0.2, 2.0))])
def test_guaranteed_and_found_bracket_the_true_margin(lin, band, f, d):
    items = _one_mode(band, f, d)
    truth = _true_margin(lin, items, fw_span=2 * (1 - f[0]))
    assert math.isfinite(truth)
    res = robust_stability(lin, items, samples=10, grid=5, k_max=4.0)
    g, found = res["margin_guaranteed"], res["margin_found"]
    resolution = 0.01 * truth        # the truth's own grid and bisection
    assert g <= truth + resolution                       # a certificate never overshoots
    assert found >= truth - resolution                   # a found point is a real one
    # tolerances stated: the certificate within 5 % of the truth on one mode (measured
    # 0.7 %), the search within 3 % (its bisection stops at 1 %)
    assert g >= 0.95 * truth
    assert found <= 1.03 * truth + resolution
    assert res["certificate_detail"]["model_check"] < 1e-6


def test_model_check_and_coverage(lin):
    from orchestrator.analysis._threads import blas_thread_counts

    uset = uncertain_set(lin, _one_mode((0.1, 1000)))
    counts = blas_thread_counts()
    res = certify(lin, uset)
    # its worker threads' one BLAS thread each is given back to the process (before,
    # the process computed on one thread from then on, and built FMUs in other bits)
    assert blas_thread_counts() == counts
    assert res["complete"] and res["opened"] == []
    assert res["model_check"] < 1e-6
    assert res["period_s"] == pytest.approx(4e-3)
    assert 0 < res["margin_guaranteed"] < 2


def test_gains_and_several_rates_are_not_certified(lin, suite_fmu_dir):
    gain = [Uncertain("g", "gain", Distribution("uniform", 0.5, 1.5), instances=("ctrl_diag",))]
    res = robust_stability(lin, gain + _one_mode((40, 50)), samples=2, grid=2)
    assert res["margin_guaranteed"] is None and "gain" in res["certificate"]
    shipped = linearize(SHIPPED, fmu_dir=suite_fmu_dir)
    res = certify(shipped, uncertain_set(shipped, _one_mode((40, 50))))
    assert res["margin_guaranteed"] is None and not res["complete"]
    assert "not for the whole loop" in res["certificate"]


_SET = """[uncertainty]
samples = 4
seed = 3

[[uncertainty.parameters]]
name = "frequencies"
kind = "modal_frequency"
distribution = "uniform"
low = 0.95
high = 1.05
per_mode = true
band = [40.0, 50.0]

[[uncertainty.parameters]]
name = "damping"
kind = "modal_damping"
distribution = "uniform"
low = {low}
high = 2.0
per_mode = true
band = [40.0, 50.0]
"""


def test_analyze_prints_and_writes_the_bracket(single_rate, suite_fmu_dir, tmp_path, capsys):
    import json

    from orchestrator.cli import main

    u = tmp_path / "u.toml"
    u.write_text(_SET.format(low=0.5), encoding="utf-8")
    out = tmp_path / "r.json"
    assert main(["analyze", str(single_rate), "--fmu-dir", str(suite_fmu_dir),
                 "--uncertainty", str(u), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "margin guaranteed: 1.4" in text and "the whole set proven stable" in text
    rob = json.loads(out.read_text(encoding="utf-8"))["robust"]
    assert rob["margin_guaranteed"] <= rob["margin_found"]
    assert rob["margin_gap"] == pytest.approx(rob["margin_found"] - rob["margin_guaranteed"])


@pytest.mark.parametrize("low,words", [(-0.5, "low >= 0"), (0.0, "expected low > 0")])
def test_a_set_reaching_zero_damping_is_refused_in_one_sentence(single_rate, suite_fmu_dir,
                                                               tmp_path, capsys, low, words):
    from orchestrator.cli import main

    u = tmp_path / "u.toml"
    u.write_text(_SET.format(low=low), encoding="utf-8")
    assert main(["analyze", str(single_rate), "--fmu-dir", str(suite_fmu_dir),
                 "--uncertainty", str(u)]) != 0
    captured = capsys.readouterr()
    err = [x for x in captured.err.strip().splitlines() if not x.startswith("(run with")
           and not x.startswith("jitterfmu: analyze ")]          # the stage lines
    assert len(err) == 1 and "damping" in err[0] and words in err[0]
    assert "robust stability" not in captured.out       # refused before any computation


@pytest.mark.slow
def test_two_modes_phase_stabilised_through_one_channel(suite_fmus, suite_fmu_dir):
    """The shipped EOS roll loop phase-stabilises the 0.5 Hz solar array mode (+32 dB of
    loop gain) beside the 1.407 Hz roll mode, both through the roll torque.  Bounding the
    coupling entrywise multiplies the array mode's open deviation by it: the pair then
    certified only 0.056, each mode alone 2.0 and 1.55.  The second test closes each
    mode's own loop exactly and keeps the couplings' phase; the pair must certify close to
    the tighter mode alone, and never above a destabilising point the search finds."""
    from orchestrator.experiments.eos import FMUS, SCENARIO

    suite_fmus(*FMUS)
    lin = linearize(SCENARIO, fmu_dir=suite_fmu_dir)
    alone = [certify(lin, uncertain_set(lin, _one_mode(b)), k_max=4.0)["margin_guaranteed"]
             for b in ([0.45, 0.55], [1.3, 1.5])]
    pair_set = _one_mode([0.45, 1.5])
    pair = certify(lin, uncertain_set(lin, pair_set), k_max=4.0)["margin_guaranteed"]
    assert pair <= min(alone) * (1 + 1e-9)        # a superset is proven no further
    assert pair >= 0.9 * min(alone)               # measured: 1.543 against 1.550
    res = robust_stability(lin, pair_set, samples=6, seed=1, grid=3, k_max=4.0)
    assert res["margin_found"] is not None
    assert pair <= res["margin_found"]            # the found point is unstable
    assert res["margin_guaranteed"] == pytest.approx(pair, rel=1e-9)
