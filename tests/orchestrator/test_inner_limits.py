"""Limits that act inside a step: the piezo amplifiers move in internal sub-steps (10 us
in a 0.5 ms step), and their rails and current limit act at each of them.

The co-simulation reports a limit reached at any sub-step (the FMUs' sticky ``sat_*``
flags, into ``run.json``'s ``saturation``); the linear engine checks the values at every
sub-step (the piezo block's ``inner`` rows) and refuses a record that reaches one, where
checking the tick values alone would return a record the co-simulation does not follow.
Reference: the co-simulation of the same scenario.
"""

from __future__ import annotations

import json
import tomllib
import warnings

import numpy as np
import pytest

from orchestrator import run_scenario
from orchestrator.analysis import linearize
from orchestrator.analysis.fast import FastResponse, NonlinearError
from orchestrator.cosim.errors import SaturationWarning

SCENARIO = "scenarios/truss10_closed_loop.toml"
P = 5e-4


@pytest.fixture(scope="module")
def fmus(suite_fmus, suite_fmu_dir):
    from orchestrator.experiments.truss_decay import FMUS

    suite_fmus(*FMUS)
    return suite_fmu_dir


def _truss(amp1):
    """The truss loop with its shipped gains, structure and amplifiers at 0.5 ms, the
    controllers on from the start and the diagonal excited at ``amp1`` V, for 2 s."""
    with open(SCENARIO, "rb") as f:
        sc = tomllib.load(f)
    for name in ("structure", "piezo_diag", "piezo_long"):
        sc["fmus"][name]["period"] = P
    for m in ("diag", "long"):
        sc["fmus"][f"piezo_{m}"]["parameters"] = {"hold_step": P}
        sc["fmus"][f"ctrl_{m}"]["parameters"] = {"t_on": 0.0}
    sc["fmus"]["excitation"]["parameters"]["amp1"] = amp1
    sc["experiment"].update(stop=2.0, output_interval=P)
    sc["record"] = {"variables": ["structure.strain_diag", "piezo_diag.current",
                                  "piezo_diag.sat_slew"]}
    return sc


def _fast(sc, fmus):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lin = linearize(sc, fmu_dir=fmus)
    fr = FastResponse(lin, ["structure.strain_diag", "piezo_diag.current"])
    K = int(round(sc["experiment"]["stop"] / lin.base))
    return fr, fr.input_matrix(fr.source_series(K), K)


def test_a_current_limit_reached_only_inside_steps_is_refused_and_reported(fmus, tmp_path):
    """At 300 V the diagonal's current stays below its 50 mA limit at every tick (96 %)
    but passes it inside steps (103 %): the linear engine refuses, naming the instance,
    and the co-simulation of the same scenario reports the limit in run.json."""
    sc = _truss(300.0)
    fr, W = _fast(sc, fmus)
    rec = fr.run(W, check=False)
    i_max = 0.05
    at_ticks = np.abs(rec.column("piezo_diag.current")).max() / i_max
    assert 0.9 < at_ticks < 1.0                       # the ticks alone see no limit
    assert rec.limits["piezo_diag.current"] > 1.0     # the sub-steps do
    assert rec.reached == ("piezo_diag.current",)
    with pytest.raises(NonlinearError, match=r"^piezo_diag\.current reaches its current "
                                             r"\(slew\) limit inside the step from t = "):
        fr.run(W)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = run_scenario(sc, tmp_path / "run", fmu_dir=fmus)
    meta = json.loads((tmp_path / "run" / "run.json").read_text())
    flagged = {(s["instance"], s["flag"]) for s in meta.get("saturation", [])}
    assert ("piezo_diag", "sat_slew") in flagged
    # the co-simulation's current at the ticks is below the limit too: only the sticky
    # flag tells
    assert np.abs(res.table["piezo_diag.current"]).max() < i_max
    assert np.max(res.table["piezo_diag.sat_slew"]) == 1.0


def test_below_the_limit_inside_steps_the_record_is_the_cosimulation(fmus, tmp_path):
    """At 250 V (86 % inside steps) nothing is refused or flagged and the linear record
    equals the co-simulation to round-off."""
    sc = _truss(250.0)
    fr, W = _fast(sc, fmus)
    rec = fr.run(W)
    assert 0.8 < rec.limits["piezo_diag.current"] < 1.0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = run_scenario(sc, fmu_dir=fmus)
    assert not [w for w in caught if issubclass(w.category, SaturationWarning)]
    y = np.asarray(res.table["structure.strain_diag"])
    lin = rec.column("structure.strain_diag")[:len(y)]
    assert np.abs(lin - y).max() < 1e-9 * np.abs(y).max()


@pytest.mark.parametrize("amp1", [300.0, 250.0, 60.0])
def test_bounded_limits_inside_steps_reach_what_the_sub_steps_reach(fmus, amp1):
    """What a Monte Carlo asks (``bound_limits``): a limit inside steps cleared by the
    rows' largest values is not evaluated sub-step by sub-step, its fraction an upper
    bound of the exact one; one the bound does not clear is evaluated, so ``reached``
    is the exact one at 300 V (103 %), 250 V (86 %) and 60 V."""
    fr, W = _fast(_truss(amp1), fmus)
    exact = fr.run_many([W], check=False)[0]
    bounded = fr.run_many([W], check=False, bound_limits=True)[0]
    assert bounded.reached == exact.reached == (("piezo_diag.current",) if amp1 > 280
                                                else ())
    for ref, used in exact.limits.items():
        assert bounded.limits[ref] >= used * (1 - 1e-12), ref
    if amp1 < 100:   # the longerons' current is far inside: bounded, not evaluated
        assert bounded.limits["piezo_long.current"] > 2 * exact.limits["piezo_long.current"]
    # the recorded line is the same to round-off: the two runs compute different sets
    # of rows, one product of another width (its last bits follow the BLAS tiling)
    y = exact.column("structure.strain_diag")
    np.testing.assert_allclose(bounded.column("structure.strain_diag"), y, rtol=0.0,
                               atol=1e-13 * np.abs(y).max())


def _full_extremes(G, Y):
    V = Y @ G.T
    return V.max(), V.min()


@pytest.mark.parametrize("shape", ["segment", "ray", "plane", "solid", "point"])
def test_the_extreme_sub_steps_hold_every_extreme(shape):
    """The sub-steps :func:`_extreme_rows` keeps hold the largest and smallest value over
    all sub-steps for any state (here 2000 random ones): points on a segment (an
    amplifier's voltage, ``e x + (1 - e) u``), on a ray through the origin (its current),
    in a plane, in space, and all equal."""
    from orchestrator.analysis.fastparts import _extreme_rows

    rng = np.random.default_rng(7)
    e = np.exp(-np.linspace(0.0, 12.0, 100))
    G = {"segment": np.c_[e, 1.0 - e, np.zeros(100)],
         "ray": 0.13 * e[:, None] * np.array([-1.0, 1.0, 0.0]),
         "plane": (lambda a, b: np.c_[a, b, a + 2 * b])(*rng.standard_normal((2, 100))),
         "solid": rng.standard_normal((100, 3)),
         "point": np.ones((100, 3))}[shape]
    rows = _extreme_rows(G)
    assert rows.size < G.shape[0]            # something is left out
    Y = rng.standard_normal((2000, 3)) * np.array([1.0, 1e3, 1e-3])
    V = Y @ G.T
    Vr = Y @ G[rows].T
    scale = np.abs(Y).max() * np.abs(G).max()
    assert np.abs(V.max(axis=1) - Vr.max(axis=1)).max() <= 1e-14 * scale
    assert np.abs(V.min(axis=1) - Vr.min(axis=1)).max() <= 1e-14 * scale
    assert _extreme_rows(G) is rows          # kept


def test_inner_limits_from_the_extreme_sub_steps_equal_every_sub_step():
    """A limit checked on the extreme sub-steps gives the fraction used of every
    sub-step to round-off, and at the edge of the range (within 1e-9 of it) every
    sub-step is evaluated: the same first step and value as the full evaluation; a
    side without a limit (infinite) the same."""
    from orchestrator.analysis import fastparts

    rng = np.random.default_rng(3)
    e = np.exp(-np.linspace(0.0, 12.0, 100))
    G = np.c_[e, 1.0 - e, np.zeros(100)]
    Y = rng.standard_normal((5000, 3))
    top, bottom = (Y @ G.T).max(), (Y @ G.T).min()
    for lo, hi in ((-10.0, 10.0), (bottom * 1.5, top * 0.9), (bottom, top),
                   (bottom * (1 - 1e-12), top * (1 + 1e-12)), (-np.inf, top * 0.9),
                   (bottom * 1.5, np.inf), (-np.inf, np.inf)):
        got = fastparts._inner_used(G, Y, lo, hi)
        fastparts._EXTREME[id(G)] = (G, np.arange(100))   # every sub-step
        full = fastparts._inner_used(G, Y, lo, hi)
        fastparts._EXTREME.pop(id(G))
        assert got[1:] == full[1:]
        assert abs(got[0] - full[0]) <= 1e-14 * abs(full[0])


def test_an_inner_bound_of_every_record_at_once_is_each_records():
    """The bound of a limit inside a step for several records' state bounds at once (one
    product) is the bound of each record's alone, and above every sub-step's value."""
    from orchestrator.analysis.fastparts import _inner_bound

    rng = np.random.default_rng(12)
    G = rng.standard_normal((100, 5))
    B = np.abs(rng.standard_normal((5, 7)))
    got = _inner_bound(G, B)
    want = np.array([_inner_bound(G, b) for b in B.T])
    np.testing.assert_allclose(got, want, rtol=1e-15, atol=0)
    for e in range(B.shape[1]):   # states inside their bounds: every sub-step below
        y = B[:, e] * rng.uniform(-1.0, 1.0, (1000, 5))
        assert np.abs(y @ G.T).max() <= got[e]


def test_the_rows_no_limit_inside_a_step_reads_are_left_out(fmus, monkeypatch):
    """A piezo block's sub-step matrices read its state and its voltage command, not the
    stack's elongation (a column of zeros in each): that input's row is not among the
    recorded rows, each limit's matrix is the block's on the columns kept, and it is
    the same array in every loop built from the same block (its extreme rows are kept
    by id).  Reference: the loop built with every input's row (the whole matrices), whose
    limits at every sub-step and records are the same."""
    from orchestrator.analysis import fast, fastparts

    sc = _truss(60.0)
    fr, W = _fast(sc, fmus)
    lin = fr.lin
    basis, inner = fastparts._inner_basis(lin, 0)
    assert len(inner) == 4                      # two blocks, voltage and current each
    whole = []
    for name in ("piezo_diag", "piezo_long"):
        b = lin.blocks[name]
        sx, su, _ = lin.slots[name]
        rows = [*range(sx.start, sx.stop), *range(su.start, su.stop)]
        assert len(b.inputs) == 2
        for o, G, *_ in b.inner:
            assert not np.any(G[:, b.n + 1])    # the elongation: read by no sub-step
            assert np.any(G[:, b.n])            # the command: read
            kept = next(g for ref, g, *_ in inner if ref == f"{name}.{o}")
            np.testing.assert_array_equal(kept, G[:, : b.n + 1])
            assert kept is next(g for ref, g, *_ in fastparts._inner_basis(lin, 0)[1]
                                if ref == f"{name}.{o}")
        whole += rows
        assert rows[b.n + 1] not in basis and all(r in basis for r in rows[: b.n + 1])
    assert len(basis) == len(whole) - 2

    def every_row(lin, r0):   # the rows of every state and input, the whole matrices
        basis, inner = [], []
        for n, b in lin.blocks.items():
            if b.inner:
                sx, su, _ = lin.slots[n]
                cols = r0 + len(basis) + np.arange(b.n + len(b.inputs))
                basis += [*range(sx.start, sx.stop), *range(su.start, su.stop)]
                inner += [(f"{n}.{o}", G, lo, hi, what, cols, b.n, b.period)
                          for o, G, lo, hi, what in b.inner]
        return basis, inner

    monkeypatch.setattr(fast, "_inner_basis", every_row)
    ref = FastResponse(lin, fr.refs)
    assert ref._r == fr._r + 2
    for bound in (False, True):
        got, want = (f.run_many([W], check=False, bound_limits=bound)[0] for f in (fr, ref))
        assert got.reached == want.reached
        for k, v in want.limits.items():
            assert got.limits[k] == pytest.approx(v, rel=1e-12, abs=0.0), k
        y = want.column("structure.strain_diag")
        np.testing.assert_allclose(got.column("structure.strain_diag"), y, rtol=0.0,
                                   atol=1e-13 * np.abs(y).max())
