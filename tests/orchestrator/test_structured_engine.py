"""The structured linear engine (orchestrator.analysis.structured) against the dense one.

Reference: the dense engine (:class:`~orchestrator.analysis.fast.FastResponse` compiled on
the sample's own loop), an independent computation of the same records from the
lifted tick maps (itself checked against the tick-by-tick map and the co-simulation in
test_linear_engine.py).  Records to 1e-12 of each record's peak, the rails reached and
the unstable poles the same, on nominal, perturbed and unstable samples of the EOS
budget (isolation off and on) and of the ten-bay truss.
"""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np
import pytest

from orchestrator.analysis import fastparts, structured
from orchestrator.analysis.blocks import structure_block
from orchestrator.analysis.fast import FastResponse
from orchestrator.analysis.structured import (ModalLoop, StructuredResponse,
                                              StructureRefused, modal_loop, respond)
from orchestrator.analysis.sweep import unstable_poles
from orchestrator.campaign import LinearRunner, load_campaign
from orchestrator.experiments.eos import CAMPAIGN as EOS_CAMPAIGN

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def truss_loop(suite_fmus, suite_fmu_dir):
    from tests.orchestrator.test_truss10_campaign import CAMPAIGN, FMUS
    suite_fmus(*FMUS)
    camp = load_campaign(CAMPAIGN)
    runner = LinearRunner(camp.scenario_dir, fmu_dir=suite_fmu_dir)
    return runner.compiled(camp.cases[0].scenario)


def _sample(lin, rng, freq=0.05, damp=(0.5, 2.0), mode=None, factor=None):
    """``lin`` with its structure's modes perturbed as a Monte Carlo sample does."""
    name = next(n for n, b in lin.blocks.items() if b.kind == "structure")
    b = lin.blocks[name]
    n = b.model.n_modes
    f_w = rng.uniform(1 - freq, 1 + freq, n)
    f_z = rng.uniform(*damp, n)
    if mode is not None:
        f_w[mode], f_z[mode] = 1.0, factor
    model = dataclasses.replace(b.model, omega=b.model.omega * f_w,
                                modal_damping=b.model.modal_damping * f_w * f_z)
    return lin.with_block(structure_block(model, name, b.period, b.period * lin.base,
                                          b.feedthrough, blockwise=True))


def _assert_same_records(got, want):
    for g, w in zip(got, want, strict=True):
        peak = np.maximum(np.nanmax(np.abs(w.values), axis=0), 1e-300)
        assert np.array_equal(np.isnan(g.values), np.isnan(w.values))
        assert np.nanmax(np.abs(g.values - w.values) / peak) < 1e-12
        assert g.reached == w.reached


def _nominal_and_perturbed_equal(fr, rng, n):
    """The nominal loop and ``n - 1`` perturbed samples: structured records and poles
    equal to the dense engine's."""
    W = rng.standard_normal((401, fr.m))
    for i in range(n):
        lin = fr.lin if i == 0 else _sample(fr.lin, rng)
        got = respond(lin, fr.refs, fr)
        assert isinstance(got, StructuredResponse), fr.structure_reason
        want = FastResponse(lin, fr.refs, like=fr)
        _assert_same_records(got.run_many([W], check=False), want.run_many([W], check=False))
        assert unstable_poles(got) == unstable_poles(want)


@pytest.mark.parametrize("config", ["isolation off", "isolation on"])
def test_the_form_rebuilds_the_eos_tick_maps(eos_loops, config):
    """Modal 2x2 blocks (70 modes and the 69 rotated Ritz modes) plus coupling through
    the structure's inputs and the other states rebuild every tick map of the loop to
    round-off (the Ritz rotation's off-block round-off is all that is dropped); the
    coupling is low rank (a product costs well under a dense one)."""
    fr = eos_loops[0][config]
    loop = modal_loop(fr)
    assert isinstance(loop, ModalLoop), fr.structure_reason
    assert loop.form_error < 1e-13
    assert loop.n_p == 2 * (70 + 69)
    for sig in loop._base:
        f = loop._form(sig, loop.block)
        assert f.step_cost() < 0.5 * 2 * f.s ** 2
        # the products of the form are those of its dense map
        rng = np.random.default_rng(0)
        X, O = rng.standard_normal((f.s, 3)), rng.standard_normal((4, f.s))
        M = f.dense()
        np.testing.assert_allclose(f.right(X), M @ X, rtol=0, atol=1e-12 * np.abs(M @ X).max())
        np.testing.assert_allclose(f.left(O), O @ M, rtol=0, atol=1e-12 * np.abs(O @ M).max())
        for L in (1, 7, 99):
            np.testing.assert_allclose(f.power(L), np.linalg.matrix_power(M, L), rtol=0,
                                       atol=1e-12 * np.abs(np.linalg.matrix_power(M, L)).max())


@pytest.mark.parametrize("config", ["isolation off", "isolation on"])
def test_the_forms_products_are_exact_entry_by_entry(eos_loops, config):
    """``O M`` and ``M X`` by the form (the coupling rows that do not read the pairs
    left out of the pair columns) within the round-off bound of each entry: the tick
    maps' entries span 1e-16 to 3e11 with isolation on, so a tolerance on the largest
    entry alone would not see an error in the structure's columns.  Reference: the dense
    product, and the bound ``n eps (|O| |M|)`` with ``|M|`` of the form's own factors."""
    fr = eos_loops[0][config]
    loop = modal_loop(fr)
    skipped = []
    for sig in loop._base:
        f = loop._form(sig, loop.block)
        n_p, k = f.n_p, f.k_in
        M = f.dense()
        Mabs = np.zeros_like(M)
        Mabs[:n_p] = np.abs(f.gamma) @ np.abs(f.W[:k])
        Mabs[n_p:] = np.abs(f.W[k:])
        i = np.arange(0, n_p, 2)
        for r, c in ((0, 0), (0, 1), (1, 0), (1, 1)):
            Mabs[i + r, i + c] += np.abs(f.a[:, r, c])
        rng = np.random.default_rng(1)
        # rows and columns of mixed scales, as the memory state's are
        scale = 10.0 ** rng.uniform(-12, 6, f.s)
        X = rng.standard_normal((f.s, 5)) * scale[:, None]
        O = rng.standard_normal((6, f.s)) / scale
        tol = 4 * f.s * np.finfo(float).eps
        assert np.all(np.abs(f.right(X) - M @ X) <= tol * (Mabs @ np.abs(X)))
        assert np.all(np.abs(f.left(O) - O @ M) <= tol * (np.abs(O) @ Mabs))
        skipped.append(f.W.shape[0] - f._parts()[0].size)
    # every map has coupling rows that do not read the pairs: the kernel leaves them out
    assert all(skipped)


def test_power_chains_compose_the_power_at_the_fewest_flops():
    """``_power_chain``: ``k 2^j + r = L`` and no cheaper way of the same kind, against a
    search over every ``(k, j)`` with ``k 2^j <= L`` and the binary digits of ``L``, for
    products from 1/20 of a squaring to one."""
    for c in (0.05, 0.125, 0.39, 1.0):
        for L in range(2, 200):
            chain, cost = fastparts._power_chain(L, 1.0, c)
            binary = (L.bit_length() - 1) + (bin(L).count("1") - 1) * c
            every = [(k - 1 + L - k * 2 ** j) * c + j for j in range(L.bit_length())
                     for k in range(1, (L >> j) + 1)]
            assert cost == pytest.approx(min(every + [binary]), rel=1e-12)
            if chain is None:
                assert cost == pytest.approx(binary, rel=1e-12)
            else:
                k, j, r = chain
                assert k * 2 ** j + r == L
                assert cost == pytest.approx((k - 1 + r) * c + j, rel=1e-12)
    # a product at an eighth of a squaring (500 modes, isolation on): 4.75 against 6.375
    assert fastparts._power_chain(99, 1.0, 0.125) == ((12, 3, 3), pytest.approx(4.75))


def test_every_way_of_the_power_and_the_period_map_equal_the_dense_ones(eos_loops,
                                                                          monkeypatch):
    """With isolation on (a coupling dense enough for squaring), ``M^99`` by each kind of
    chain and by the coupling's rows (``_coupled_power``) equals
    ``numpy.linalg.matrix_power`` of the dense tick map to 1e-12 of its largest entry,
    and the row and column Krylov products of that run equal ``C M^q`` and ``M^q N`` of
    the dense map to 1e-12 of theirs; the super-period map (the ACS tick's map
    multiplied as a structured one) equals the product of the dense maps to the same."""
    fr = eos_loops[0]["isolation on"]
    loop = modal_loop(fr)
    sig = next(s for s, L in fr._runs if L == 99)
    f = loop._form(sig, loop.block)
    M = f.dense()
    ref = np.linalg.matrix_power(M, 99)
    C, N = loop._base[sig]["C"], f.N[:, :5]
    O_ref, K_ref = [C], [N]
    for _ in range(98):
        O_ref.append(O_ref[-1] @ M)
        K_ref.append(M @ K_ref[-1])
    O_ref, K_ref = np.array(O_ref), np.stack(K_ref, axis=1)
    scale = np.minimum(np.abs(ref).max(axis=1, keepdims=True),
                       np.abs(ref).max(axis=0, keepdims=True))
    ways = [(c, 0.0) for c in (None, (3, 5, 3), (12, 3, 3), (99, 0, 0), (1, 6, 35))]
    coupled = []
    monkeypatch.setattr(structured, "_coupled_power",
                        lambda *a: coupled.append(1) or fastparts._coupled_power(*a))
    for chain in ways + [(None, np.inf)]:   # an infinite squaring: the coupling's rows
        monkeypatch.setattr(structured, "_power_chain", lambda L, sq, pr, c=chain: c)
        P, O, K = f.run(99, C, N)
        assert np.abs(P - ref).max() <= 1e-12 * np.abs(ref).max(), chain
        # and each entry to 1e-8 of the smaller of its row's and its column's largest:
        # an error in the rows and columns of small scale (amplifiers, controllers)
        # shows there (numpy's binary squaring and each way agree to 1.8e-10 by it)
        assert np.all(np.abs(P - ref) <= 1e-8 * scale), chain
        assert np.abs(O - O_ref).max() <= 1e-12 * np.abs(O_ref).max(), chain
        assert np.abs(K - K_ref).max() <= 1e-12 * np.abs(K_ref).max(), chain
        assert len(coupled) == (chain[1] == np.inf)
    monkeypatch.undo()
    got = loop.nominal()
    Phi = None
    for s, L in fr._runs:
        Md = np.linalg.matrix_power(loop._form(s, loop.block).dense(), L)
        Phi = Md if Phi is None else Md @ Phi
    assert np.abs(got.period_map() - Phi).max() <= 1e-12 * np.abs(Phi).max()


@pytest.mark.parametrize("config", ["isolation off", "isolation on"])
def test_structured_records_equal_the_dense_engine_on_eos(eos_loops, config):
    """Nominal and perturbed samples (frequencies +-5 %, damping x0.5-2 per mode): every
    record of a batch (random sources on every channel) equal to the dense engine's to
    1e-12 of its peak; with the Monte Carlo's bounded limits and skipped start too; the
    rails reached and the unstable poles the same."""
    fr = eos_loops[0][config]
    rng = np.random.default_rng(1)
    Ws = [rng.standard_normal((801, fr.m)) for _ in range(3)]
    for i in range(3):
        lin = fr.lin if i == 0 else _sample(fr.lin, rng)
        got = respond(lin, fr.refs, fr)
        assert isinstance(got, StructuredResponse)
        want = FastResponse(lin, fr.refs, like=fr)
        _assert_same_records(got.run_many(Ws, check=False), want.run_many(Ws, check=False))
        kw = dict(check=False, bound_limits=True, start=300)
        _assert_same_records(got.run_many(Ws, **kw), want.run_many(Ws, **kw))
        assert unstable_poles(got) == unstable_poles(want) == []


def old_acs_loop(eos_loops) -> tuple:
    """The isolation-off RWA loop with the ACS it had before its redesign (0.1 Hz on the
    rigid body), and the index of its 2.58 Hz mode, which that ACS destabilises below
    a threshold damping."""
    _, runner, cases = eos_loops
    old = copy.deepcopy(cases["isolation off"].scenario)
    old["fmus"]["acs"]["parameters"].update(
        bandwidth=0.1, bandwidth_x=0.0, bandwidth_y=0.0, phase_margin=math.radians(50.0),
        notch_hz_x=0.0, lowpass_hz_x=0.0, lowpass_hz_y=0.0, lowpass_hz_z=0.0)
    fr = runner.compiled(old)
    f = fr.lin.blocks["structure"].model.frequencies_hz
    return fr, int(np.argmin(np.abs(f - 2.58)))


@pytest.mark.long   # make test-full: eigenvalues of unstable samples on both engines, 7 s
def test_unstable_samples_have_the_same_poles(eos_loops):
    """The EOS loop with the ACS it had before its redesign (0.1 Hz on the rigid body)
    takes damping from its 2.58 Hz mode: samples around that mode's threshold damping
    are unstable or not, and the structured loop's poles outside the unit circle are
    the dense loop's (verdict and values), its records too (a growing record)."""
    fr, mode = old_acs_loop(eos_loops)
    rng = np.random.default_rng(2)
    verdicts = []
    W = rng.standard_normal((801, fr.m))
    for factor in np.linspace(0.6, 1.8, 9):
        lin = _sample(fr.lin, rng, freq=0.0, damp=(1.0, 1.0), mode=mode, factor=factor)
        got, want = respond(lin, fr.refs, fr), FastResponse(lin, fr.refs, like=fr)
        assert isinstance(got, StructuredResponse)
        pg, pw = unstable_poles(got), unstable_poles(want)
        assert len(pg) == len(pw)
        np.testing.assert_allclose(np.sort_complex(np.array(pg)),
                                   np.sort_complex(np.array(pw)), rtol=1e-9)
        verdicts.append(bool(pw))
        _assert_same_records(got.run_many([W], check=False), want.run_many([W], check=False))
    assert verdicts[0] and not verdicts[-1]     # both kinds among the samples


@pytest.mark.long   # make test-full
def test_stability_verdicts_equal_eigenvalues_on_200_samples(eos_loops):
    """200 samples of the isolation-on loop, every mode perturbed and the 146.95 Hz bus
    mode's damping drawn around where the MISR struts destabilise it (x0.2-0.6 of its
    nominal, the marginal samples of the shipped Monte Carlo): the verdict of the
    structured loop is that of the dense loop's eigenvalues on every one."""
    fr = eos_loops[0]["isolation on"]
    f = fr.lin.blocks["structure"].model.frequencies_hz
    mode = int(np.argmin(np.abs(f - 146.95)))
    rng = np.random.default_rng(3)
    agree, unstable = 0, 0
    for factor in rng.uniform(0.2, 0.6, 200):
        lin = _sample(fr.lin, rng, freq=0.01, damp=(0.9, 1.1), mode=mode, factor=factor)
        a = bool(unstable_poles(respond(lin, fr.refs, fr)))
        b = bool(unstable_poles(FastResponse(lin, fr.refs, like=fr)))
        agree += a == b
        unstable += b
    assert agree == 200
    assert 0 < unstable < 200     # near-marginal: both verdicts occur


def test_truss_structured_equals_dense_and_is_not_chosen(truss_loop, monkeypatch):
    """The ten-bay truss (6 modes, 2 Ritz vectors, two strain loops: 22 memory states)
    is coupled on most of its states: a product with its structured map costs about
    half a dense one, so the dense engine runs it and says why.  Forced, the structured
    form gives the dense records all the same (runs of 1 and 3 ticks, nominal and
    perturbed)."""
    fr = truss_loop
    got = respond(fr.lin, fr.refs, fr)
    assert type(got) is FastResponse
    assert "not low rank" in fr.structure_reason and "dense engine" in fr.structure_reason
    monkeypatch.setattr(structured, "_PAYS", 1.0)
    del fr._modal
    _nominal_and_perturbed_equal(fr, np.random.default_rng(4), 3)
    del fr._modal


def test_a_sample_that_changes_more_than_the_modes_runs_dense(eos_loops):
    """A structure whose output rows differ, or another block changed (a controller's
    gain), is not a patch of the nominal form: refused in one sentence by the form, and
    run by the dense engine through :func:`respond`."""
    fr = eos_loops[0]["isolation on"]
    loop = modal_loop(fr)
    b = loop.block
    moved = dataclasses.replace(b, C=b.C * 1.001)
    with pytest.raises(StructureRefused, match="changes its output rows"):
        loop.sample(moved)
    got = respond(fr.lin.with_block(moved), fr.refs, fr)
    assert type(got) is FastResponse
    ctrl = fr.lin.controllers(active_only=True)[0]
    assert type(respond(fr.lin.with_gain(ctrl, 0.9), fr.refs, fr)) is FastResponse


def test_a_ritz_block_equal_to_round_off_is_the_nominal_ones(eos_loops):
    """A sample's static Ritz block computed on another count of BLAS threads differs
    from the nominal one in its last bits: that sample is still structured (its records
    the dense engine's on its own block, to 1e-12 of peak); a Ritz block changed by
    1e-9 is refused."""
    fr = eos_loops[0]["isolation off"]
    loop = modal_loop(fr)
    b = loop.block
    nm, nr = b.model.n_modes, b.model.n_ritz
    o = slice(2 * nm, 2 * nm + 2 * nr)
    rng = np.random.default_rng(6)
    for eps, structured_ in ((4e-16, True), (1e-9, False)):
        A, B = b.A.copy(), b.B.copy()
        A[o, o] *= 1 + eps * rng.standard_normal(A[o, o].shape)
        B[o] *= 1 + eps * rng.standard_normal(B[o].shape)
        lin = fr.lin.with_block(dataclasses.replace(b, A=A, B=B))
        got = respond(lin, fr.refs, fr)
        assert isinstance(got, StructuredResponse) is structured_
        if structured_:
            W = rng.standard_normal((401, fr.m))
            _assert_same_records(got.run_many([W], check=False),
                                 FastResponse(lin, fr.refs, like=fr).run_many([W], check=False))
        else:
            with pytest.raises(StructureRefused, match="static Ritz block"):
                loop.sample(lin.blocks[loop.name], lin)


def test_monte_carlo_samples_equal_with_either_engine(eos_loops, monkeypatch):
    """Two samples of the shipped EOS Monte Carlo (12 events x 2 configurations, 8 s
    records, metrics and statuses): the same numbers through the structured loops as
    through the dense ones."""
    from orchestrator.analysis.uncertainty import draw
    from orchestrator.campaign import montecarlo as mcm

    _, runner, _ = eos_loops
    camp = load_campaign(EOS_CAMPAIGN, EOS_CAMPAIGN.parent / "eos_uncertainty.toml", 2)
    ctx = mcm._setup(camp, runner)
    lin0, structs, _ = ctx["base"][ctx["configs"][0]]
    draws = draw(camp.uncertainty["parameters"], 2, camp.uncertainty["seed"],
                 lin0.blocks[structs[0]].model.frequencies_hz)
    v_s, st_s = mcm._evaluate(camp, runner, ctx, draws, [0, 1])
    monkeypatch.setattr(structured, "_PAYS", 0.0)    # the dense engine everywhere
    for cf in ctx["configs"]:
        del ctx["base"][cf][2]._modal
    v_d, st_d = mcm._evaluate(camp, runner, ctx, draws, [0, 1])
    for cf in ctx["configs"]:   # the loops are the module's: found again by later tests
        del ctx["base"][cf][2]._modal
    # the outcomes equal (rails, instability); the bits of how the engine took them
    # say which ran: structured (isolation off counted, on by eigenvalues), then dense
    assert np.array_equal(st_s & 7, st_d & 7)
    assert (st_s & 8 == 0).all() and (st_d & 8 != 0).all() and (st_d & 16 != 0).all()
    assert (st_s[:, ctx["configs"].index("isolation off")] & 16 == 0).all()
    assert (st_s[:, ctx["configs"].index("isolation on")] & 16 != 0).all()
    assert np.all(np.isfinite(v_d))
    np.testing.assert_allclose(v_s, v_d, rtol=1e-10)


@pytest.mark.long   # make test-full: reduces a 300-mode model, 6 s
def test_a_300_mode_model_reduces_and_runs_structured(eos_loops, monkeypatch):
    """The EOS testbed reduced to 300 modes (with its 59 Ritz vectors, which at that
    count are 1e-6 of their static shapes beside the eigenvectors and were refused as
    a singular Ritz block): the basis is mass-orthonormal, and its loop (isolation on)
    gives the dense engine's records through the structured one, nominal and perturbed,
    its 99-tick run's ``M^L`` from the coupling's rows (fewer flops than squaring at this
    size)."""
    from structfmu.fem import assemble
    from structfmu.models import eos_testbed as et
    from structfmu.reduce import reduce

    truss = et.build(active_legs="all")     # as eos.mounts_structure_model, 300 modes
    sel = [c.name for c in truss.input_channels if c.name.startswith("fc_")]
    model, T = reduce(truss, 300, ritz_inputs=sel + list(et.load_inputs()), shift=et.SHIFT,
                      damping=et.damping(300, truss), return_basis=True)
    model = dataclasses.replace(model, accel_lowpass=et.ACCEL_LOWPASS)
    M = assemble(truss)[1]
    assert np.abs(T.T @ (M @ T) - np.eye(T.shape[1])).max() < 1e-12
    fr0 = eos_loops[0]["isolation on"]
    b = fr0.lin.blocks["structure"]
    lin = fr0.lin.with_block(structure_block(model, "structure", b.period,
                                             b.period * fr0.lin.base, b.feedthrough,
                                             blockwise=True))
    fr = FastResponse(lin, fr0.refs)
    assert fr.n_memory > 2 * (300 + 59)
    coupled = []
    monkeypatch.setattr(structured, "_coupled_power",
                        lambda *a: coupled.append(1) or fastparts._coupled_power(*a))
    _nominal_and_perturbed_equal(fr, np.random.default_rng(5), 2)
    assert coupled   # the 99-tick runs' M^L
