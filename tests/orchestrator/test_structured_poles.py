"""Unstable poles from the structure (orchestrator.analysis.structpoles) against eigenvalues.

Reference: ``numpy.linalg.eigvals`` of the dense matrix ``D + U W`` (synthetic loops)
or of the loop's balanced super-period map (EOS), counted at ``|z| > 1 + 1e-6`` as
:func:`~orchestrator.analysis.sweep.unstable_poles` counts them.  The count by the
argument principle must equal it, or be None (not certain: the eigenvalues decide)
only where an eigenvalue lies on the circle to round-off.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from orchestrator.analysis import structpoles
from orchestrator.analysis.fast import FastResponse
from orchestrator.analysis.steady import balance
from orchestrator.analysis.structpoles import period_split, unstable_count, winding_count
from orchestrator.analysis.structured import StructuredResponse, respond
from orchestrator.analysis.sweep import unstable_poles
from tests.orchestrator.test_structured_engine import _sample, old_acs_loop

TOL = 1e-6


def _loop(rng, n_pairs=40, n_rest=4, k_in=3, rigid=2, rank=2):
    """A synthetic ``D + U W``: lightly damped pairs (|z| 0.95-0.9999), ``rigid``
    Jordan blocks at 1, ``n_rest`` other states; the coupling reads the pairs through
    ``rank`` combinations."""
    r, phi = rng.uniform(0.95, 0.9999, n_pairs), rng.uniform(0.0, np.pi, n_pairs)
    c, s = r * np.cos(phi), r * np.sin(phi)
    A = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    A[:rigid] = [[1.0, 0.1], [0.0, 1.0]]
    n_p = 2 * n_pairs
    k = k_in + n_rest
    U = np.zeros((n_p + n_rest, k))
    U[:n_p, :k_in] = rng.standard_normal((n_p, k_in))
    U[n_p:, k_in:] = np.eye(n_rest)
    W = np.hstack([rng.standard_normal((k, rank)) @ rng.standard_normal((rank, n_p)),
                   rng.standard_normal((k, n_rest))])
    return A, U, W, n_p


def _dense(A, U, W, n_p):
    """Eigenvalues outside ``1 + TOL`` and the spectral radius of ``D + U W``."""
    M = U @ W
    for j, a in enumerate(A):
        M[2 * j:2 * j + 2, 2 * j:2 * j + 2] += a
    ev = np.abs(np.linalg.eigvals(balance(M)[0]))
    return int(np.sum(ev > 1 + TOL)), float(ev.max())


def test_the_winding_counts_the_eigenvalues_outside_the_circle():
    """300 synthetic loops (10 draws, coupling gains 1e-4 to 1; half with their rigid
    bodies driven, which splits their Jordan blocks out of the circle): the count equals
    the eigenvalues' on every one, stable and unstable ones among them."""
    rng = np.random.default_rng(7)
    counts = []
    for draw in range(10):
        A, U, W, n_p = _loop(rng)
        if draw % 2:
            U[:4] = 0.0
        for g in np.geomspace(1e-4, 1.0, 30):
            want, _ = _dense(A, g * U, W, n_p)
            assert winding_count(A, g * U, W, n_p, TOL)[0] == want
            counts.append(want)
    assert counts.count(0) > 20 and max(counts) >= 4


def test_near_the_circle_the_count_is_exact_or_defers_to_the_eigenvalues():
    """Gains bisected to where a pair leaves the circle (the rigid bodies' Jordan blocks
    not driven, one by round-off): 1e-3 and 1e-6 (relative) either side the count is
    the eigenvalues'; at the crossing itself it is theirs or None, and None only where
    an eigenvalue is on the circle to 1e-12."""
    rng = np.random.default_rng(11)
    exact = deferred = 0
    for _ in range(30):
        A, U, W, n_p = _loop(rng)
        U[:4] = 0.0
        U[2:4] = 1e-17 * rng.standard_normal((2, U.shape[1]))
        g = np.geomspace(1e-3, 3.0, 40)
        out = np.array([_dense(A, x * U, W, n_p)[1] > 1 + TOL for x in g])
        if not np.diff(out).any():   # stable (or unstable) at every gain: no crossing
            continue
        i = int(np.flatnonzero(np.diff(out))[0])
        lo, hi = g[i], g[i + 1]
        for _ in range(60):
            m = math.sqrt(lo * hi)
            lo, hi = (m, hi) if (_dense(A, m * U, W, n_p)[1] > 1 + TOL) == out[i] else (lo, m)
        for x in (lo * (1 - 1e-3), lo * (1 - 1e-6), hi * (1 + 1e-6), hi * (1 + 1e-3)):
            assert winding_count(A, x * U, W, n_p, TOL)[0] == _dense(A, x * U, W, n_p)[0]
            exact += 1
        for x in (lo, hi):
            want, radius = _dense(A, x * U, W, n_p)
            got = winding_count(A, x * U, W, n_p, TOL)[0]
            assert got == want or (got is None and abs(radius - 1 - TOL) < 1e-12)
            deferred += got is None
        if exact == 24:
            break
    assert exact == 24          # six crossings


def test_blocks_outside_the_circle_count_without_any_coupling():
    """A pair at |z| = 1.01 that the coupling neither reads nor drives is an unstable
    pole of the map; with no coupling at all the count is the blocks' alone, and with
    a coupling that reads no pair, the blocks' and the other states' own."""
    rng = np.random.default_rng(5)
    A, U, W, n_p = _loop(rng)
    A[5] = 1.01 * np.eye(2)
    U[10:12] = 0.0
    W[:, 10:12] = 0.0
    want, _ = _dense(A, 1e-3 * U, W, n_p)
    assert want >= 2
    assert winding_count(A, 1e-3 * U, W, n_p, TOL)[0] == want
    assert winding_count(A, U[:, :0], W[:0], n_p, TOL) == (2, 0)
    W[:, :n_p] = 0.0              # the coupling reads no pair: blocks and the rest's own
    want, _ = _dense(A, U, W, n_p)
    assert winding_count(A, U, W, n_p, TOL)[0] == want >= 2


def test_the_eos_period_map_is_its_pairs_powers_plus_low_rank(eos_loops):
    """Isolation off, the pairs run free between ACS ticks: the super-period map is
    ``blockdiag(a^100) + (M^99 U) W`` (18 coupling columns) to round-off of the dense
    product of the run maps, on the states that drive the structure; the recorded
    accelerometers' filters (24 states, at 1 kHz) only read it, and their own map is
    the block of theirs.  Isolation on, the 1 kHz loops read the pairs at every tick:
    the split refuses and says so, and the dense eigenvalues decide."""
    fr = eos_loops[0]["isolation off"]
    got = respond(fr.lin, fr.refs, fr)
    assert isinstance(got, StructuredResponse)
    split, why = period_split(got)
    assert why is None and split.U.shape[1] == split.W.shape[0] == 18
    P = np.asarray(got.period_map())
    M = split.U @ split.W
    for j, a in enumerate(split.A):
        M[2 * j:2 * j + 2, 2 * j:2 * j + 2] += a
    keep, watch = split.states, np.setdiff1d(np.arange(P.shape[0]), split.states)
    assert watch.size == split.watch.shape[0] == 24
    scale = np.abs(P).max()
    assert np.abs(M - P[np.ix_(keep, keep)]).max() < 1e-13 * scale
    assert np.abs(split.watch - P[np.ix_(watch, watch)]).max() < 1e-13 * scale
    assert not P[np.ix_(keep, watch)].any()          # nothing of the loop reads them
    ev = np.abs(np.linalg.eigvals(balance(P)[0]))
    assert unstable_count(got) == int(np.sum(ev > 1 + TOL)) == 0
    on = eos_loops[0]["isolation on"]
    got = respond(on.lin, on.refs, on)
    split, why = period_split(got)
    assert split is None and "100 of the super-period's 100 ticks" in why
    assert unstable_count(got) is None
    assert period_split(on)[0] is None and "not in its structured form" in period_split(on)[1]


def test_an_unstable_watch_block_is_counted(eos_loops, monkeypatch):
    """The filters' own block made unstable (its map scaled to spectral radius 1.2):
    the count is the winding of the stable rest plus that block's poles outside, equal
    to the eigenvalues of the whole block-triangular map built with it."""
    fr = eos_loops[0]["isolation off"]
    got = respond(fr.lin, fr.refs, fr)
    split, _ = period_split(got)
    rho = np.abs(np.linalg.eigvals(split.watch)).max()
    bad = split._replace(watch=split.watch * (1.2 / rho))
    P = np.asarray(got.period_map()).copy()
    watch = np.setdiff1d(np.arange(P.shape[0]), split.states)
    P[np.ix_(watch, watch)] = bad.watch
    want = int(np.sum(np.abs(np.linalg.eigvals(balance(P)[0])) > 1 + TOL))
    assert want > 0
    monkeypatch.setattr(structpoles, "period_split", lambda _: (bad, None))
    assert unstable_count(got, TOL) == want


def test_eos_counts_equal_eigenvalues_on_perturbed_samples(eos_loops):
    """20 perturbed samples of the isolation-off loop (every mode's frequency +-5 %,
    damping x0.5-2): the count is that of the balanced super-period map's eigenvalues,
    and the verdict that of the dense engine's loop."""
    fr = eos_loops[0]["isolation off"]
    rng = np.random.default_rng(8)
    for _ in range(20):
        lin = _sample(fr.lin, rng)
        got = respond(lin, fr.refs, fr)
        ev = np.linalg.eigvals(balance(np.asarray(got.period_map()))[0])
        assert unstable_count(got, TOL) == int(np.sum(np.abs(ev) > 1 + TOL))
        assert unstable_poles(got) == unstable_poles(FastResponse(lin, fr.refs, like=fr)) == []


@pytest.mark.long   # make test-full: 200 samples and the bisected threshold, 30 s
def test_eos_verdicts_equal_eigenvalues_on_200_samples_and_at_the_threshold(eos_loops,
                                                                            monkeypatch):
    """200 samples of the isolation-off loop with the ACS it had before its redesign,
    whose 2.58 Hz mode goes unstable below a threshold damping: that mode's damping
    drawn across the threshold, every other mode perturbed.  Then that damping bisected
    to the threshold: 1e-3 and 1e-6 either side.  The count equals the eigenvalues' on every
    sample, or is None where an eigenvalue is on the circle to round-off; the verdict
    of :func:`unstable_poles` equals the dense engine's on every tenth sample and the
    four beside the threshold."""
    fr, mode = old_acs_loop(eos_loops)
    rng = np.random.default_rng(9)

    def count(factor, freq=0.05, damp=(0.5, 2.0), verdicts=True):
        lin = _sample(fr.lin, rng, freq=freq, damp=damp, mode=mode, factor=factor)
        got = respond(lin, fr.refs, fr)
        ev = np.abs(np.linalg.eigvals(balance(np.asarray(got.period_map()))[0]))
        want = int(np.sum(ev > 1 + TOL))
        if verdicts:   # the engines' own: the structured count, the dense eigenvalues
            assert bool(unstable_poles(got)) == bool(unstable_poles(
                FastResponse(lin, fr.refs, like=fr))) == (want > 0)
        return unstable_count(got, TOL), want, ev.max()

    unstable = 0
    for i, factor in enumerate(rng.uniform(0.6, 1.8, 200)):
        got, want, _ = count(factor, verdicts=i % 10 == 0)
        assert got == want
        unstable += want > 0
    assert 20 < unstable < 180          # both kinds, many of each
    lo, hi = 0.6, 1.8                   # the threshold of the nominal other modes
    for _ in range(50):
        m = (lo + hi) / 2
        lo, hi = (m, hi) if count(m, 0.0, (1.0, 1.0), False)[1] else (lo, m)
    for factor in (lo * (1 - 1e-3), lo * (1 - 1e-6), hi * (1 + 1e-6), hi * (1 + 1e-3)):
        got, want, _ = count(factor, 0.0, (1.0, 1.0))
        assert got == want
    for factor in (lo, hi):   # on the circle to round-off: two dense engines may differ
        got, want, radius = count(factor, 0.0, (1.0, 1.0), False)
        assert got == want or (got is None and abs(radius - 1 - TOL) < 1e-9)


@pytest.mark.parametrize("radius", [0.9999, 1.0001])
def test_two_poles_close_together_and_to_the_circle_are_counted(radius):
    """Two conjugate pairs of the other states 1e-5 apart, 1e-4 from the circle, where
    no block of the structure is near: between two points the phase turns by a whole
    turn, which only the dip of the magnitude shows.  Inside they are no unstable pole,
    outside they are four; a coupling that reads no pair leaves the blocks' own."""
    rng = np.random.default_rng(1)
    A, U, W, n_p = _loop(rng, n_pairs=6, n_rest=4, rigid=0)
    A[:] = 0.99 * np.array([[np.cos(2.5), -np.sin(2.5)], [np.sin(2.5), np.cos(2.5)]])
    k_in = 3
    U[:n_p] *= 1e-3               # the pairs' own coupling weak: they stay inside
    W[k_in:] = 0.0                # the other states neither read the pairs
    W[:k_in, n_p:] = 0.0          # nor drive them: their own two pairs
    for j, r in enumerate((radius, radius + 1e-5)):
        W[k_in + 2 * j:k_in + 2 * j + 2, n_p + 2 * j:n_p + 2 * j + 2] = r * np.array(
            [[np.cos(1.0), -np.sin(1.0)], [np.sin(1.0), np.cos(1.0)]])
    want, _ = _dense(A, U, W, n_p)
    assert want == (4 if radius > 1 else 0)
    assert winding_count(A, U, W, n_p, TOL)[0] == want


def test_an_unsettled_winding_defers_to_the_eigenvalues(monkeypatch):
    """With a cap below the points a loop needs, the count is None, not a guess."""
    A, U, W, n_p = _loop(np.random.default_rng(3))
    assert winding_count(A, 0.01 * U, W, n_p, TOL)[0] is not None
    monkeypatch.setattr(structpoles, "_CAP", 100)
    assert winding_count(A, 0.01 * U, W, n_p, TOL)[0] is None


def test_loop_eigenvalues_balance_once_and_set_idle_states_apart():
    """A map of known eigenvalues (pairs on and either side of the circle, a Jordan
    block at 1), its states scaled over 1e-6..1e6 and three states zero up to round-off
    (1e-40 of its largest entry): ``loop_eigenvalues`` gives those eigenvalues (and 0
    for the idle states) within the round-off their conditioning allows, and the count
    outside ``1 + 1e-6`` of ``eigvals(balance(A))``."""
    from orchestrator.analysis.steady import loop_eigenvalues

    rng = np.random.default_rng(11)
    n_pairs = 30
    r = np.concatenate([rng.uniform(0.9, 0.999, n_pairs - 4), [1.01, 1.0 + 1e-4, 1.002, 0.5]])
    phi = rng.uniform(0.05, 3.0, n_pairs)
    want = np.concatenate([r * np.exp(1j * phi), r * np.exp(-1j * phi), [1.0, 1.0]])
    n = 2 * n_pairs + 2
    B = np.zeros((n, n))
    for j in range(n_pairs):
        c, s = r[j] * np.cos(phi[j]), r[j] * np.sin(phi[j])
        B[2 * j:2 * j + 2, 2 * j:2 * j + 2] = [[c, -s], [s, c]]
    B[-2:, -2:] = [[1.0, 0.1], [0.0, 1.0]]
    Q = np.linalg.qr(rng.standard_normal((n, n)))[0]
    d = 10.0 ** rng.uniform(-6, 6, n)
    A0 = (Q @ B @ Q.T) / d[:, None] * d[None, :]
    A = np.zeros((n + 3, n + 3))
    A[:n, :n] = A0
    A[n:, :] = 1e-40 * np.abs(A0).max() * rng.standard_normal((3, n + 3))
    A[:, n:] = 1e-40 * np.abs(A0).max() * rng.standard_normal((n + 3, 3))
    got = loop_eigenvalues(A)
    assert np.sum(np.abs(got) < 1e-12) == 3
    ev = np.sort_complex(got[np.abs(got) >= 1e-12])
    assert np.abs(ev - np.sort_complex(want)).max() < 1e-6   # the Jordan block: sqrt(eps)
    simple = np.abs(np.abs(want) - 1.0) > 1e-9
    for z in want[simple]:   # the simple ones to round-off
        assert np.abs(got - z).min() < 1e-10
    ref = np.linalg.eigvals(balance(A)[0])
    assert np.sum(np.abs(got) > 1 + TOL) == np.sum(np.abs(ref) > 1 + TOL) == 6


def test_isolation_on_verdicts_by_loop_eigenvalues_equal_the_balanced_maps(eos_loops):
    """16 isolation-on samples (the loop whose poles the dense eigenvalues decide) with
    the 146.95 Hz bus mode's damping drawn where the MISR struts destabilise it: the
    verdict, and the poles outside, of :func:`unstable_poles` are those of the balanced
    super-period map's eigenvalues (to sqrt(eps) of the circle, where the free rigid
    body's double poles sit)."""
    fr = eos_loops[0]["isolation on"]
    f = fr.lin.blocks["structure"].model.frequencies_hz
    mode = int(np.argmin(np.abs(f - 146.95)))
    rng = np.random.default_rng(12)
    unstable = 0
    for factor in np.linspace(0.2, 0.6, 16):
        lin = _sample(fr.lin, rng, freq=0.01, damp=(0.9, 1.1), mode=mode, factor=factor)
        got = respond(lin, fr.refs, fr)
        ev = np.linalg.eigvals(balance(np.asarray(got.period_map()))[0])
        want = sorted((z for z in ev if abs(z) > 1 + TOL), key=abs, reverse=True)
        poles = unstable_poles(got)
        assert len(poles) == len(want)
        assert all(abs(p - w) < 1e-7 for p, w in zip(poles, want))
        unstable += bool(want)
    assert 0 < unstable < 16     # both verdicts occur
