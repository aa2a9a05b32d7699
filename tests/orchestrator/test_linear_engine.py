"""The linear engine for campaigns (orchestrator.analysis.fast, orchestrator.campaign.linear).

References: the tick-by-tick linear map (:meth:`LinearScenario.simulate`, itself equal to
the co-simulation of a linear scenario) and the co-simulated campaign of the same cases,
every summary cell; a rail or a nonlinear element is refused in one sentence.
"""

from __future__ import annotations

import math

import dataclasses
import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from orchestrator.analysis import AnalysisError
from orchestrator.campaign import (CampaignError, LinearRunner, MasterRunner,
                                   campaign_from_dict, keyed, load_campaign, run_campaign,
                                   verify_campaign)
from orchestrator.experiments import eos
from orchestrator.experiments.eos import CAMPAIGN as EOS_CAMPAIGN

pytestmark = pytest.mark.slow

# a slew (edges) and a harmonic source; a scan and a chopper (edges too) in make test-full
EOS_EVENTS = ("SWIR pointing", "RWA")
MORE_EVENTS = ("CERES scan", "TIR chopper")
EOS_STOP = 3.0


def _summary(folder):
    return {(r["case"], r["instrument"], r["axis"], r["metric"], r["window"]): r["value"]
            for r in pq.read_table(folder / "summary.parquet").to_pylist()}


def _eos_campaign(events=EOS_EVENTS, stop=EOS_STOP):
    camp = load_campaign(EOS_CAMPAIGN)
    cases = []
    for c in camp.cases:
        if c.event in events:
            sc = json.loads(json.dumps(c.scenario))
            sc["experiment"]["stop"] = stop
            cases.append(dataclasses.replace(c, scenario=sc, key=c.key + "-short"))
    return dataclasses.replace(camp, cases=tuple(cases))


@pytest.fixture(scope="module")
def eos_fmus(suite_fmu_dir):
    return eos.ensure_fmus(suite_fmu_dir)


def _pair(camp, out, eos_fmus):
    """``camp`` co-simulated and through the linear engine, into ``out``."""
    co = run_campaign(camp, out / "cosim", MasterRunner(camp.scenario_dir, fmu_dir=eos_fmus),
                      workers=2, progress=False)
    runner = LinearRunner(camp.scenario_dir, fmu_dir=eos_fmus)
    li = run_campaign(dataclasses.replace(camp, engine="linear"), out / "linear", runner,
                      progress=False)
    return camp, out, co, li, runner


@pytest.fixture(scope="module")
def eos_pair(tmp_path_factory, eos_fmus):
    """The same EOS cases co-simulated and through the linear engine."""
    return _pair(_eos_campaign(), tmp_path_factory.mktemp("linear_eos"), eos_fmus)


def test_linear_campaign_equals_cosimulation_eos(eos_pair):
    """Every summary cell (cases, RSS) of the multi-rate EOS budget (10 Hz ACS, fifteen
    1 kHz loops), isolation off and on, to 1e-9 relative."""
    _summaries_agree(*eos_pair[:4])


@pytest.mark.long   # make test-full: eight more co-simulated EOS cases, 12 s
def test_linear_campaign_equals_cosimulation_eos_scan_and_chopper(tmp_path, eos_fmus):
    """The same for the CERES scan and the TIR chopper (sources with edges)."""
    _summaries_agree(*_pair(_eos_campaign(MORE_EVENTS), tmp_path, eos_fmus)[:4])


def _summaries_agree(camp, out, co, li):
    assert co.n_failed == li.n_failed == 0
    a, b = _summary(out / "cosim"), _summary(out / "linear")
    # every instrument axis of every case, and the RSS rows
    n_axes = sum(len(axes) for axes in camp.instruments.values())
    assert set(a) == set(b) and len(a) > n_axes * len(camp.cases)
    worst = max(abs(a[k] - b[k]) / abs(a[k]) for k in a if a[k] != 0)
    assert worst < 1e-9, worst
    assert json.loads((out / "linear" / "campaign.json").read_text())["engine"] == "linear"


def test_linear_record_equals_cosimulated_record(eos_pair, eos_fmus):
    """The recorded table itself, column by column, not only its metrics."""
    camp, out, *_ = eos_pair
    case = next(c for c in keyed(camp, LinearRunner(camp.scenario_dir, eos_fmus)).cases
                if c.event == "SWIR pointing")
    co_case = next(c for c in keyed(camp, MasterRunner(camp.scenario_dir, eos_fmus)).cases
                   if c.label == case.label)
    lin = pq.read_table(out / "linear" / "cases" / case.key / "results.parquet").to_pydict()
    co = pq.read_table(out / "cosim" / "cases" / co_case.key / "results.parquet").to_pydict()
    assert list(lin) == list(co)
    np.testing.assert_array_equal(lin["time"], co["time"])
    for name in co:
        x, y = np.asarray(co[name]), np.asarray(lin[name])
        scale = max(np.max(np.abs(x)), 1e-300)
        assert np.max(np.abs(x - y)) <= 1e-9 * scale, name


def test_a_linear_case_names_the_limits_a_bound_cleared(eos_pair, eos_fmus):
    """A linear case computes a checked output that it does not record only where a
    bound does not clear it: ``run.json`` gives the exact fraction of each range used
    for the others (``limits_used``) and that bound for these (``limits_bound``, at or
    above the exact fraction of the whole record), every checked output in one of the
    two."""
    camp, out, *_ = eos_pair
    runner = LinearRunner(camp.scenario_dir, eos_fmus)
    case = next(c for c in keyed(camp, runner).cases
                if c.event == "SWIR pointing" and c.configuration == "isolation on")
    meta = json.loads((out / "linear" / "cases" / case.key / "run.json").read_text())
    used, bound = meta["limits_used"], meta["limits_bound"]
    fr = runner.compiled(case.scenario)
    exact = fr.run(runner.inputs(fr, case.scenario), check=False).limits
    assert set(used) | set(bound) == set(exact) and not set(used) & set(bound)
    assert bound, "the isolation-on loop's piezo limits are cleared by their bounds"
    for ref, value in used.items():
        assert value == pytest.approx(exact[ref], rel=1e-12, abs=1e-15), ref
    for ref, value in bound.items():
        assert value >= exact[ref] * (1 - 1e-12), ref


def _isolation_on_loop(eos_pair):
    """The compiled loop of the short EOS campaign with isolation on."""
    runner = eos_pair[-1]
    case = next(c for c in _eos_campaign().cases if c.configuration == "isolation on")
    return runner.compiled(case.scenario)


def test_fast_response_equals_the_tick_by_tick_map(eos_pair, eos_fmus):
    """All sources driven at once with seeded noise; the ACS at 10 Hz makes the tick map
    periodic over 100 ticks, run as one tick plus a run of 99."""
    fr = _isolation_on_loop(eos_pair)
    n_ticks = 450
    rng = np.random.default_rng(7)
    W = rng.standard_normal((n_ticks + 1, fr.m))
    rec = fr.run(W, check=False)
    refs = [r for r in rec.refs if not fr._is_flag(r)]

    def w(name, k):
        off = fr._in_off[name]
        return W[k, off:off + len(fr.lin.blocks[name].outputs)]

    want, _ = fr.lin.simulate(n_ticks + 1, w=w, record=refs)
    got = np.column_stack([rec.column(r) for r in refs])
    scale = np.maximum(np.abs(want).max(axis=0), 1e-300)
    assert np.max(np.abs(got - want) / scale) < 1e-11
    assert [L for _, L in fr._runs] == [1, 99]


def test_records_computed_together_equal_each_alone(eos_pair):
    """run_many (one state recursion and one free-response product for a configuration's
    events) against run of each record: different channels driven, one record at rest,
    one driving every channel."""
    fr = _isolation_on_loop(eos_pair)
    n_ticks = 350
    rng = np.random.default_rng(11)
    Ws = []
    for cols in ([0], [3, 7, 8], [], list(range(fr.m))):
        W = np.zeros((n_ticks + 1, fr.m))
        W[:, cols] = rng.standard_normal((n_ticks + 1, len(cols)))
        Ws.append(W)
    together = fr.run_many(Ws, check=False)
    for W, got in zip(Ws, together):
        want = fr.run(W, check=False)
        scale = np.maximum(np.abs(want.values).max(axis=0), 1e-300)
        assert np.max(np.abs(got.values - want.values) / scale) < 1e-12
        # fractions of each rail used: what decides is the distance to the rail (1), so
        # the tolerance is absolute in units of the rail
        assert got.limits == pytest.approx(want.limits, rel=0, abs=1e-12)
    assert not np.any(together[2].values) and together[2].reached == ()
    # checked outputs bounded instead of computed: the same references, and every bound
    # at or above the fraction of its range the record uses
    bounded = fr.run_many(Ws, check=False, bound_limits=True)
    for got, want in zip(bounded, together):
        # fewer rows in the products: equal to round-off of the sums, whatever the BLAS
        scale = np.maximum(np.abs(want.values).max(axis=0), 1e-300)
        assert np.max(np.abs(got.values - want.values) / scale) < 1e-12
        assert got.reached == want.reached
        for ref, used in want.limits.items():
            assert got.limits[ref] >= used * (1 - 1e-12), ref
    # and some were bounded, not computed (a bound is above the exact fraction)
    assert any(got.limits[ref] > want.limits[ref] * (1 + 1e-9)
               for got, want in zip(bounded, together) for ref in want.limits)
    # what a Monte Carlo asks: the references from tick 205 on (runs that end before it
    # compute their checked rows only), the channels each record drives given
    late = fr.run_many(Ws, check=False, bound_limits=True, start=205,
                       actives=[np.flatnonzero(np.any(W != 0.0, axis=0)) for W in Ws])
    los = [j for j, r in enumerate(fr.refs) if ".los_" in r]
    for got, want in zip(late, bounded):
        assert np.isnan(got.values[:200, los]).all() and not np.isnan(got.values[205:]).any()
        scale = np.maximum(np.abs(want.values).max(axis=0), 1e-300)
        assert np.max(np.abs(got.values[205:] - want.values[205:]) / scale) < 1e-12
        assert got.reached == want.reached
        assert got.limits == pytest.approx(want.limits, rel=0, abs=1e-12)   # of the rail



def test_run_views_are_the_rows_of_evenly_spaced_runs():
    """The in-place views of a run type's rows: each record's runs, run after run, are
    exactly ``Y[e, win]`` (written through the view, read by indexing); runs not evenly
    spaced, or filling only some columns, get no view."""
    from orchestrator.analysis.fastparts import _run_views

    Y = np.zeros((3, 41, 4))
    win = 1 + 10 * np.arange(4)[:, None] + np.arange(9)     # the 9-tick runs of period 10
    views = _run_views(Y, win, True)
    marks = np.arange(views.size, dtype=float).reshape(views.shape) + 1.0
    views[...] = marks
    np.testing.assert_array_equal(Y[:, win.ravel()].reshape(marks.shape), marks)
    untouched = np.setdiff1d(np.arange(41), win.ravel())
    assert not Y[:, untouched].any()
    assert _run_views(Y, win, False) is None
    assert _run_views(Y, win[[0, 1, 3]], True) is None
    assert _run_views(Y, np.array([[0, 1, 2], [2, 3, 4]]), True) is None   # overlapping
    assert _run_views(Y[:, :, :2], win, True) is None                     # not contiguous


def test_records_written_in_place_equal_the_copied_ones(eos_pair, monkeypatch):
    """run_many writes each run type's free and forced rows straight into the records;
    the same records as through a temporary, both bit for bit on the free part's products
    (one product per record either way) and with the rows bounded."""
    from orchestrator.analysis import fast

    fr = _isolation_on_loop(eos_pair)
    rng = np.random.default_rng(3)
    Ws = []
    for cols in ([0], [3, 7, 8]):
        W = np.zeros((451, fr.m))
        W[:, cols] = rng.standard_normal((451, len(cols)))
        Ws.append(W)
    runs = {}
    for name, views in (("in place", fast._run_views), ("copied", lambda *a: None)):
        monkeypatch.setattr(fast, "_run_views", views)
        runs[name] = fr.run_many(Ws, check=False, bound_limits=True, start=120)
    for got, want in zip(runs["in place"], runs["copied"]):
        np.testing.assert_array_equal(got.values, want.values)
        assert got.limits == want.limits and got.reached == want.reached


def test_runs_without_input_skip_their_forced_part(eos_pair, monkeypatch):
    """A source quiet in most runs (a pulse at 0.15 s, a burst from 0.33 s, one record at
    rest): the forced parts of the runs with input alone give the records of every run's
    forced part, bit for bit, and only those runs are transformed."""
    from orchestrator.analysis import fast

    fr = _isolation_on_loop(eos_pair)
    rng = np.random.default_rng(6)
    W = np.zeros((451, fr.m))
    W[150, 3] = 1.0
    W[330:360, [7, 8]] = rng.standard_normal((30, 2))
    Ws = [W, np.zeros_like(W)]
    seen = []

    def every(out, Wu, forced, t, active, sel):
        out += forced(t, active, Wu, sel)

    def counted(t, active, Wu, sel):
        seen.append(Wu.shape[0])
        return forced(t, active, Wu, sel)

    forced = fr._forced
    monkeypatch.setattr(fr, "_forced", counted)
    got = fr.run_many(Ws, check=False, bound_limits=True, start=120)
    runs_with_input = sum(seen)
    monkeypatch.setattr(fast, "_add_forced", every)
    seen.clear()
    want = fr.run_many(Ws, check=False, bound_limits=True, start=120)
    assert runs_with_input < sum(seen)
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a.values, b.values)
        assert a.limits == b.limits and a.reached == b.reached


def test_limit_bounds_equal_their_formula(eos_pair):
    """The bounds of the checked rows (their row Krylov products' largest magnitudes,
    taken tick by tick) equal ``sum_j max_q |(C M^q)_ij| |x_0j| + sum_c (sum_p |h_p|_ic)
    max_l |w_lc|`` written out whole."""
    from orchestrator.analysis.fastparts import _limit_bounds

    fr = _isolation_on_loop(eos_pair)
    t = fr._type(*fr._runs[-1])
    pos = np.flatnonzero(t.live >= len(fr._computed))
    rng = np.random.default_rng(8)
    X = rng.standard_normal((2, 5, fr.n_memory))
    active = np.array([3, 7])
    Wus = [rng.standard_normal((5, t.L, active.size)) for _ in range(2)]
    fr._kernels.clear()
    got = _limit_bounds(fr, t, pos, X, Wus, [active, active[:0]])
    A = np.abs(t.O.reshape(t.L, t.live.size, -1)[:, pos]).max(axis=0)
    h1 = np.abs(fr._columns(t, active)[1][:, pos]).sum(axis=0)
    want = np.abs(X) @ A.T
    want[0] += np.abs(Wus[0]).max(axis=1) @ h1.T
    np.testing.assert_array_equal(fr._kernels[("absmax", id(t), pos.tobytes())], A)
    np.testing.assert_allclose(got, want.max(axis=1), rtol=1e-14, atol=0)   # sums' order


def test_forced_response_by_toeplitz_product_equals_fft(eos_pair, monkeypatch):
    """The two ways of a run's Markov convolution (the kept block-Toeplitz product, the
    FFT) on the EOS loop's 99-tick run: equal to the round-off of an FFT (about 1e-15 of
    the largest output per transform length; 1e-12 leaves room for any BLAS)."""
    from orchestrator.analysis import fast

    fr = _isolation_on_loop(eos_pair)
    rng = np.random.default_rng(5)
    W = np.zeros((301, fr.m))
    W[:, [2, 9, 10]] = rng.standard_normal((301, 3))
    got = {}
    for limit in (0, 256):
        monkeypatch.setattr(fast, "_TOEPLITZ_TICKS", limit)
        fr._kernels.clear()
        got[limit] = fr.run(W, check=False).values
    fr._kernels.clear()
    scale = np.maximum(np.abs(got[256]).max(axis=0), 1e-300)
    assert np.max(np.abs(got[0] - got[256]) / scale) < 1e-12


@pytest.mark.parametrize("L", [1, 2, 3, 4, 8, 64, 99])
def test_powers_by_squaring_give_the_matrix_power(L):
    """``M^L`` from the doubling steps equals numpy's ``matrix_power`` for every kind of
    ``L`` (1, powers of two, odd); on a contraction (norm 0.99) both are good to about
    ``L n eps``, 1e-12 here."""
    from orchestrator.analysis.fastparts import _power, _powers

    rng = np.random.default_rng(L)
    Q, _ = np.linalg.qr(rng.standard_normal((30, 30)))
    M = 0.99 * Q
    P = _powers(M, L)
    assert len(P) == max(0, (L - 1).bit_length())   # M^(2^j) for 2^j < L
    np.testing.assert_allclose(_power(M, L, P), np.linalg.matrix_power(M, L), rtol=0,
                               atol=1e-12)


def test_krylov_products_by_doubling_equal_the_sequential_ones(eos_pair):
    """The row and column Krylov products and ``M^L`` of the EOS loop's 99-tick run,
    computed by doubling, against one product per tick.

    The tolerance comes from the conditioning of the products, not from a run: in the
    balanced coordinates (exact power-of-two scaling, which changes no rounding) any
    parenthesisation of ``C M^q`` has a first-order error of at most (its products) x
    ``n eps`` x the largest ``||C M^a|| ||M^b|| ||M^c||`` over ``a + b + c = q``
    (Frobenius norms of the exact powers, here the sequential ones), and the two ways
    differ by at most twice that.  On this BLAS they differ by 3e-7 of it; a power off
    by one, by 6e5 times it.  (An earlier tolerance, 20 times the difference between
    two other orders of the same products, failed once the run types were built under
    one BLAS thread and the check under two: 55 times that difference.)"""
    from scipy.linalg import matrix_balance

    MP = np.linalg.matrix_power
    fr = _isolation_on_loop(eos_pair)
    sig, L = max(fr._runs, key=lambda r: r[1])
    t = fr._type(sig, L)
    M, C = t.M, fr._maps[sig][2][t.live]
    ch = np.flatnonzero(np.any(t.N != 0, axis=0))[:3]
    n, eps = M.shape[0], np.finfo(float).eps
    O, K, seq = [C], [t.N[:, ch]], M
    for _ in range(1, L):
        O.append(O[-1] @ M)
        K.append(M @ K[-1])
    for _ in range(2, L + 1):
        seq = seq @ M
    G, _ = fr._columns(t, ch)
    d = matrix_balance(M, permute=False, separate=True)[1][0]     # M_b = D^-1 M D
    Mb = M / d[:, None] * d[None, :]
    norms = [np.sqrt(n)]                                           # ||M_b^j||, j = 0 .. L
    P = np.eye(n)
    for _ in range(L):
        P = Mb @ P
        norms.append(np.linalg.norm(P))
    # the largest ||M_b^b|| ||M_b^c|| with b + c = s, b >= 1
    pair = [0.0] + [max(norms[k] * norms[s - k] for k in range(1, s + 1))
                    for s in range(1, L + 1)]
    r = C.shape[0]
    rows_b = [np.linalg.norm(O[q] * d[None, :]) for q in range(L)]   # ||C_b M_b^q||
    got_O = t.O.reshape(L, r, n)
    for q in range(1, L):
        tol = 2 * 2 * q * n * eps * max(rows_b[p] * pair[q - p] for p in range(q))
        assert np.linalg.norm((got_O[q] - O[q]) * d[None, :]) <= tol, q
    Nb = np.linalg.norm(t.N[:, ch] / d[:, None])
    for q in range(1, L):      # G[:, l] holds M^(L-1-l) N, K[q] holds M^q N
        tol = 2 * 2 * q * n * eps * Nb * pair[q]
        assert np.linalg.norm((G[:, L - 1 - q] - K[q]) / d[:, None]) <= tol, q
    tol_L = 2 * 2 * L * n * eps * pair[L]
    scale = d[None, :] / d[:, None]
    assert np.linalg.norm((t.ML - seq) * scale) <= tol_L
    # and not vacuous: a power off by one is far outside
    assert np.linalg.norm((MP(M, L + 1) - seq) * scale) > 1e3 * tol_L


def test_rail_reached_is_refused_with_the_instance(eos_fmus, tmp_path):
    """A rail the linear record crosses fails the case in one sentence; nothing else."""
    camp = _eos_campaign(events=("SWIR pointing",), stop=1.5)
    on = [c for c in camp.cases if c.configuration == "isolation on"]
    sc = json.loads(json.dumps(on[0].scenario))
    params = sc["fmus"]["piezo_swir_mount1"].setdefault("parameters", {})
    params["v_min"], params["v_max"] = -1e-6, 1e-6   # |v| reaches about 3e-5 V
    runner = LinearRunner(camp.scenario_dir, fmu_dir=eos_fmus)
    with pytest.raises(AnalysisError, match=r"piezo_swir_mount1\.voltage reaches its voltage "
                                            r"rail .* at t = .* s.*--engine cosim"):
        runner(sc, tmp_path / "rail")
    # unchecked, the record says which outputs left their range (what Monte Carlo reads)
    fr = runner.compiled(sc)
    for bound in (False, True):   # a bound that does not clear the rail: computed
        rec = fr.run_many([runner.inputs(fr, sc)], check=False, bound_limits=bound)[0]
        assert "piezo_swir_mount1.voltage" in rec.reached
        assert rec.limits["piezo_swir_mount1.voltage"] > 1.0
        # checked, the sentence names the rail whichever rows were computed (the bounded
        # rows leave the record's columns)
        with pytest.raises(AnalysisError, match=r"piezo_swir_mount1\.voltage reaches"):
            fr.run_many([runner.inputs(fr, sc)], check=True, bound_limits=bound)


@pytest.mark.parametrize("param, value, words", [
    ("hysteresis", True, "hysteresis on"),
    ("noise_std", 1e-6, "strain-gauge noise on"),
    ("resolution", 1e-9, "quantises its strain"),
])
def test_unmodelled_element_is_refused_before_running(eos_fmus, tmp_path, param, value,
                                                      words):
    camp = _eos_campaign(events=("SWIR pointing",), stop=1.5)
    sc = json.loads(json.dumps(camp.cases[0].scenario))
    sc["fmus"]["piezo_iso2"].setdefault("parameters", {})[param] = value
    runner = LinearRunner(camp.scenario_dir, fmu_dir=eos_fmus)
    with pytest.raises(AnalysisError, match=f"piezo_iso2.*{words}"):
        runner(sc, tmp_path / "x")
    assert not (tmp_path / "x" / "results.parquet").exists()


def test_recording_an_output_the_model_leaves_out_is_refused(eos_fmus, tmp_path):
    camp = _eos_campaign(events=("SWIR pointing",), stop=1.5)
    sc = json.loads(json.dumps(camp.cases[0].scenario))
    sc["record"]["variables"].append("acs.wheel_speed_x")
    runner = LinearRunner(camp.scenario_dir, fmu_dir=eos_fmus)
    with pytest.raises(AnalysisError, match="acs.wheel_speed_x .*wheel speeds are not in the "
                                            "linear model"):
        runner(sc, tmp_path / "x")


def test_verify_reports_the_difference_per_axis(eos_pair, eos_fmus):
    camp, out, *_ = eos_pair
    lcamp = keyed(dataclasses.replace(camp, engine="linear"),
                  LinearRunner(camp.scenario_dir, fmu_dir=eos_fmus))
    rep = verify_campaign(lcamp, out / "linear", 1, fmu_dir=eos_fmus)
    assert rep["n"] == 1 and not rep["nonlinear"]
    assert set(rep["largest_difference"]) == {f"{i}/{a}" for i, axes in
                                              camp.instruments.items() for a in axes}
    assert max(d["metric"] for d in rep["largest_difference"].values()) < 1e-9
    assert rep["cases"][0]["nonlinear_flags"] == []
    on_disk = json.loads((out / "linear" / "verify.json").read_text())
    assert on_disk["n"] == 1


@pytest.mark.parametrize("head, words", [
    ({"engine": "fast"}, "engine is 'fast'; expected one of"),
    ({"verify": -1}, "verify is -1; expected a whole number"),
    ({"verify": 1.5}, "verify is 1.5"),
])
def test_bad_engine_settings_are_one_sentence(head, words):
    data = {"campaign": {"name": "x", "scenario": {
        "experiment": {"stop": 0.1}, "fmus": {"a": {"fmu": "x.fmu", "period": 1e-3}}},
        **head}, "instruments": [{"name": "i", "axes": {"x": "a.y"}}]}
    with pytest.raises(CampaignError, match=words):
        campaign_from_dict(data)


def test_fast_response_refuses_an_unknown_source(eos_pair):
    _, _, _, _, runner = eos_pair
    fr = next(iter(runner._compiled.values()))
    with pytest.raises(AnalysisError, match="'nope' is not a source of the scenario"):
        fr.input_matrix({"nope": np.zeros((3, 6))}, 2)


@pytest.mark.long   # make test-full
def test_linear_engine_on_the_truss_campaign(tmp_path, suite_fmus, suite_fmu_dir):
    """Sources at 4 ms in a 1 ms loop: the super-period is 64 ticks of runs of 1 and 3."""
    from orchestrator.campaign import ENGINES
    assert ENGINES == ("cosim", "linear")
    from tests.orchestrator.test_truss10_campaign import CAMPAIGN, FMUS
    suite_fmus(*FMUS)
    camp = load_campaign(CAMPAIGN)
    co = run_campaign(camp, tmp_path / "co", MasterRunner(camp.scenario_dir,
                                                          fmu_dir=suite_fmu_dir),
                      workers=2, progress=False)
    li = run_campaign(dataclasses.replace(camp, engine="linear"), tmp_path / "li",
                      LinearRunner(camp.scenario_dir, fmu_dir=suite_fmu_dir), progress=False)
    assert co.n_failed == li.n_failed == 0
    a, b = _summary(tmp_path / "co"), _summary(tmp_path / "li")
    assert set(a) == set(b)
    assert max(abs(a[k] - b[k]) / abs(a[k]) for k in a if a[k]) < 1e-9


def test_structure_step_matrices_are_its_step_bit_for_bit(eos_pair):
    """The structure block's (A, B), assembled from the discretised blocks (modes, Ritz
    block, accelerometer filter), are the numbers the FMU's step multiplies: stepping
    each unit state and input gives the same columns exactly."""
    from structfmu.discrete import discretize, step, step_matrices

    model = _isolation_on_loop(eos_pair).lin.blocks["structure"].model
    assert model.n_filter_states and model.n_ritz and model.n_modes
    dm = discretize(model, 1e-3)
    A, B = step_matrices(dm)
    n, m = model.n_states, model.n_inputs
    np.testing.assert_array_equal(A, np.column_stack([step(dm, e, np.zeros(m))
                                                      for e in np.eye(n)]))
    np.testing.assert_array_equal(B, np.column_stack([step(dm, np.zeros(n), e)
                                                      for e in np.eye(m)]))


def test_channel_scales_equal_scaled_inputs(eos_pair):
    """run_many's per-record channel factors (a Monte Carlo sample's amplitudes) give
    the record of the scaled input matrix, to the round-off of one multiplication."""
    fr = _isolation_on_loop(eos_pair)
    rng = np.random.default_rng(3)
    W = np.zeros((251, fr.m))
    W[:, [1, 4, 20]] = rng.standard_normal((251, 3))
    scale = rng.uniform(0.8, 1.2, fr.m)
    got = fr.run_many([W, W], check=False, scales=[scale, np.ones(fr.m)])
    want = fr.run_many([W * scale, W], check=False)
    for g, w in zip(got, want):
        peak = np.maximum(np.abs(w.values).max(axis=0), 1e-300)
        assert np.max(np.abs(g.values - w.values) / peak) < 1e-13
    with pytest.raises(Exception, match="2 channel scales for 1 input matrices"):
        fr.run_many([W], scales=[scale, scale])


def test_blockwise_filter_rows_equal_the_fmus_exponential(eos_pair):
    """The accelerometer filter's ZOH rows block by block (a Monte Carlo sample's
    structure) against the FMU's one exponential of the whole 382-state model, nominal
    and with perturbed modes: the two exponentials differ by their round-off (measured
    3.7e-13 of a column's largest entry; the tolerance leaves a factor 30 for other
    BLAS), and the perturbation is seen by both alike."""
    import dataclasses

    from structfmu.discrete import _filter_zoh, filter_zoh

    model = _isolation_on_loop(eos_pair).lin.blocks["structure"].model
    rng = np.random.default_rng(2)
    moved = dataclasses.replace(
        model, omega=model.omega * rng.uniform(0.95, 1.05, model.n_modes),
        modal_damping=model.modal_damping * rng.uniform(0.5, 2.0, model.n_modes))
    for m in (model, moved):
        want, got = _filter_zoh(m, 1e-3), filter_zoh(m, 1e-3)
        for w, g in zip(want, got):
            col = np.maximum(np.abs(w).max(axis=0), 1e-300)
            assert np.max(np.abs(g - w) / col) < 1e-11
    # the perturbation changes the modes' columns far above that round-off
    modes = slice(0, 2 * model.n_modes)
    nominal = filter_zoh(model, 1e-3)[0][:, modes]
    change = filter_zoh(moved, 1e-3)[0][:, modes] - nominal
    assert np.max(np.abs(change)) > 1e-3 * np.abs(nominal).max()


def test_states_no_record_can_need_are_dropped_exactly(eos_pair, monkeypatch):
    """With isolation off the controllers are at gain 0: their states (and what only
    they see) can change no computed output, and states no source reaches stay zero
    from rest. They leave the memory state; every record driven by every channel, and
    the loop's poles, are those of the loop that keeps them (to round-off)."""
    from orchestrator.analysis import fast
    from orchestrator.analysis.sweep import unstable_poles

    runner = eos_pair[-1]
    case = next(c for c in _eos_campaign().cases if c.configuration == "isolation off")
    fr = runner.compiled(case.scenario)
    monkeypatch.setattr(fast, "_relevant",
                        lambda maps, rows: np.ones(next(iter(maps.values()))[0].shape[0], bool))
    full = fast.FastResponse(fr.lin, fr.refs)
    assert fr.n_memory < full.n_memory
    rng = np.random.default_rng(9)
    W = rng.standard_normal((301, fr.m))
    got, want = fr.run(W, check=False), full.run(W, check=False)
    peak = np.maximum(np.abs(want.values).max(axis=0), 1e-300)
    assert np.max(np.abs(got.values - want.values) / peak) < 1e-12
    assert got.limits == pytest.approx(want.limits, rel=0, abs=1e-12)
    # the loop's slowest poles (|z| > 0.95 over the 0.1 s super-period, the rigid body's
    # double poles at 1 left out: a solver finds them to about sqrt(eps)) are the full
    # loop's: the dropped states add none and move none
    pa, pb = ([z for z in unstable_poles(r, tol=-0.05) if abs(z - 1) > 1e-4]
              for r in (fr, full))
    assert len(pa) == len(pb) > 0
    np.testing.assert_allclose(np.abs(pa), np.abs(pb), rtol=0, atol=1e-9)


def test_the_growing_eos_pole_is_the_acs_taking_damping_from_one_flexible_mode(eos_pair):
    """The old EOS loop's slowly growing pole (docs/coupling.md) was the 10 Hz ACS with
    its 0.1 Hz crossover designed on the rigid body removing damping from the 2.58 Hz
    flexible mode: it sits at that mode's frequency, it is gone with the ACS taken out,
    and that mode's damping alone moves it across the unit circle (x0.5 grows faster,
    x1.5 decays). The threshold factor lies between 1 and 1.5: what made a Monte Carlo
    with damping x0.5-2 per mode count about 40 % of its isolation-off samples unstable
    with that ACS (docs/linear_engine.md). The shipped ACS (designed on the flexible plant)
    leaves no growing pole."""
    import copy

    from orchestrator.analysis.blocks import structure_block
    from orchestrator.analysis.fast import FastResponse
    from orchestrator.analysis.sweep import unstable_poles

    runner = eos_pair[-1]
    case = next(c for c in _eos_campaign().cases if c.configuration == "isolation off")
    shipped = runner.compiled(case.scenario)
    # the ACS as it was shipped before its redesign: 0.1 Hz, designed on 1/(J s^2)
    old = copy.deepcopy(case.scenario)
    old["fmus"]["acs"]["parameters"].update(
        bandwidth=0.1, bandwidth_x=0.0, bandwidth_y=0.0, phase_margin=math.radians(50.0),
        notch_hz_x=0.0, lowpass_hz_x=0.0, lowpass_hz_y=0.0, lowpass_hz_z=0.0)
    fr = runner.compiled(old)
    lin = fr.lin
    T = fr.P * lin.base

    def growing(loop):   # complex poles outside the unit circle: (|z|, Hz)
        return [(abs(z), abs(np.angle(z)) / (2 * np.pi * T))
                for z in unstable_poles(FastResponse(loop, fr.refs)) if abs(z.imag) > 1e-9]

    poles = growing(lin)
    assert len(poles) == 2 and 1.0001 < poles[0][0] < 1.01   # one pair
    name = next(n for n, b in lin.blocks.items() if b.kind == "structure")
    b = lin.blocks[name]
    f = b.model.frequencies_hz
    mode = int(np.argmin(np.abs(f - poles[0][1])))
    assert abs(f[mode] - poles[0][1]) < 0.05 and 2.0 < f[mode] < 3.0
    assert growing(lin.opened(["acs"])) == []

    def with_damping(factor):
        c = b.model.modal_damping.copy()
        c[mode] *= factor
        return lin.with_block(structure_block(dataclasses.replace(b.model, modal_damping=c),
                                              name, b.period, b.period * lin.base,
                                              b.feedthrough, blockwise=True))

    assert growing(with_damping(0.5))[0][0] > poles[0][0]
    assert growing(with_damping(1.5)) == []
    # the shipped ACS leaves no pole outside the unit circle, even with that mode's
    # damping halved
    assert unstable_poles(FastResponse(shipped.lin, fr.refs)) == []
    b_shipped = shipped.lin.blocks[name]
    c = b_shipped.model.modal_damping.copy()
    c[mode] *= 0.5
    halved = shipped.lin.with_block(structure_block(
        dataclasses.replace(b_shipped.model, modal_damping=c), name, b_shipped.period,
        b_shipped.period * shipped.lin.base, b_shipped.feedthrough, blockwise=True))
    assert unstable_poles(FastResponse(halved, fr.refs)) == []


def test_a_samples_loop_compiled_like_its_nominal_one_gives_the_same_records(eos_pair):
    """A Monte Carlo sample's loop takes its nominal loop's memory state and builds its
    tick maps on those columns alone (``FastResponse(..., like=nominal)``): the same
    memory state and records, to the last bit here and to round-off of the products'
    shapes anywhere, as the loop found on its own; the Ritz block's discretisation is
    shared with the nominal model (the arrays kept), the modes' are the sample's own.
    A loop whose pattern differs (the isolation loops switched on) finds its own."""
    import dataclasses

    from orchestrator.analysis.blocks import structure_block
    from orchestrator.analysis.fast import FastResponse
    from orchestrator.analysis.fastparts import _same_pattern
    from structfmu.discrete import discretize

    runner = eos_pair[-1]
    cases = {c.configuration: c for c in _eos_campaign().cases if c.event == "RWA"}
    off = runner.compiled(cases["isolation off"].scenario)
    on = runner.compiled(cases["isolation on"].scenario)
    b = off.lin.blocks["structure"]
    rng = np.random.default_rng(4)
    moved = dataclasses.replace(
        b.model, omega=b.model.omega * rng.uniform(0.95, 1.05, b.model.n_modes),
        modal_damping=b.model.modal_damping * rng.uniform(0.5, 2.0, b.model.n_modes))
    assert moved.K_oo is b.model.K_oo                   # the frozen Ritz block is kept
    d0, d1 = discretize(b.model, 1e-3, True), discretize(moved, 1e-3, True)
    assert d1.Phi_o is d0.Phi_o and not np.array_equal(d1.a11, d0.a11)
    # an FMU's data are computed afresh (a kept exponential may come from another BLAS
    # thread count, which moves its last bits)
    assert discretize(moved, 1e-3).Phi_o is not d0.Phi_o
    lin = off.lin.with_block(structure_block(moved, "structure", b.period,
                                             b.period * off.lin.base, b.feedthrough,
                                             blockwise=True))
    alone, like = FastResponse(lin, off.refs), FastResponse(lin, off.refs, like=off)
    assert np.array_equal(alone._S, like._S) and _same_pattern(like, off)
    W = rng.standard_normal((401, off.m))
    got, want = like.run(W, check=False), alone.run(W, check=False)
    peak = np.maximum(np.abs(want.values).max(axis=0), 1e-300)
    assert np.max(np.abs(got.values - want.values) / peak) < 1e-12
    # isolation on drives the controllers that isolation off leaves at gain 0
    other = FastResponse(on.lin, on.refs, like=off)
    assert not _same_pattern(other, off) and other.n_memory == on.n_memory > off.n_memory


def test_channels_built_by_the_cases_of_several_threads_give_the_records(eos_pair):
    """A campaign's build leaves each channel's input side to the first case that drives
    it: eight records driving overlapping channels, asked from four threads at once of
    a loop built without its channels, equal the same records of the loop built with
    every channel (round-off of the column products' shapes); each run type, the
    records' shorter last run included, is built once and holds the driven channels
    alone."""
    from concurrent.futures import ThreadPoolExecutor

    from orchestrator.analysis.fast import FastResponse

    full = _isolation_on_loop(eos_pair)
    lazy = FastResponse(full.lin, full.refs).prepare(channels=())
    assert all(not t.cols for t in lazy._types.values())
    n_ticks = 250
    rng = np.random.default_rng(5)
    Ws = []
    for i in range(8):
        W = np.zeros((n_ticks + 1, full.m))
        cols = [i % full.m, (3 * i + 1) % full.m, (5 * i + 2) % full.m]
        W[:, cols] = rng.standard_normal((n_ticks + 1, 3))
        Ws.append(W)
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda W: lazy.run(W, check=False), Ws))
    for W, g in zip(Ws, got):
        want = full.run(W, check=False)
        scale = np.maximum(np.abs(want.values).max(axis=0), 1e-300)
        assert np.max(np.abs(g.values - want.values) / scale) < 1e-12
        assert g.reached == want.reached
    driven = {int(c) for W in Ws for c in np.flatnonzero(np.any(W != 0.0, axis=0))}
    assert [sorted(t.cols) for t in lazy._types.values()] == [sorted(driven)] * len(lazy._types)
