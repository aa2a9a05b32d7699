"""The engine's tools for sampled loops (orchestrator.analysis.sampled, .margins, .frf,
.bounds), each checked against an independent computation: a closed form, a brute-force
scan, or the same quantity computed another way (numpy.linalg.lstsq, a dense solve per
frequency, a step-by-step simulation)."""

from __future__ import annotations

import numpy as np
import pytest

from orchestrator.analysis.bounds import (best_real_gain, harmonic_ceiling,
                                          harmonic_reduction_pct, least_squares_inputs,
                                          least_squares_records, record_ceiling)
from orchestrator.analysis.frf import (closed_loop_frf, isolation_bandwidth,
                                       modal_frequency_response, transmissibility_bands)
from orchestrator.analysis.margins import (band_damping, best_direction, is_stable,
                                           loop_gain_margins_db, poles_outside,
                                           scaled_to_margins, siso_margins,
                                           spectral_radius, without_states)
from orchestrator.analysis.sampled import (amplifier_step, simulate_with_acs, stack_loop,
                                           zoh)

RNG = np.random.default_rng(20)


def _stable_system(n=6, m=2, p=3, dt=1e-3):
    """A random stable discrete system with distinct poles (modes 5-200 Hz, 1-5 %)."""
    f = RNG.uniform(5, 200, n // 2)
    z = RNG.uniform(0.01, 0.05, n // 2)
    s = np.concatenate([-z * 2 * np.pi * f + 2j * np.pi * f * np.sqrt(1 - z**2),
                        -z * 2 * np.pi * f - 2j * np.pi * f * np.sqrt(1 - z**2)])
    lam = np.exp(s * dt)
    blocks = [np.array([[l.real, -l.imag], [l.imag, l.real]]) for l in lam[: n // 2]]
    T = RNG.normal(size=(n, n))
    A = T @ np.block([[blocks[i] if i == j else np.zeros((2, 2)) for j in range(n // 2)]
                      for i in range(n // 2)]) @ np.linalg.inv(T)
    return A, RNG.normal(size=(n, m)), RNG.normal(size=(p, n)), RNG.normal(size=(p, m)), dt


# -- sampled ------------------------------------------------------------------------------
def test_zoh_of_a_first_order_lag_is_its_closed_form():
    # dx/dt = -x / tau + u / tau: x+ = e^(-h/tau) x + (1 - e^(-h/tau)) u
    tau, h = 0.02, 1e-3
    Ad, Bd = zoh(np.array([[-1 / tau]]), np.array([[1 / tau]]), h)
    np.testing.assert_allclose(Ad, [[np.exp(-h / tau)]], rtol=1e-14)
    np.testing.assert_allclose(Bd, [[1 - np.exp(-h / tau)]], rtol=1e-12)


def test_amplifier_step_is_the_amplifier_over_one_step():
    # the linear map against the amplifier's own step from a known voltage, command held
    from piezofmu.amplifier import AmplifierState, amplifier_preset, step

    amp, dt, v0, u = amplifier_preset("P-865.10"), 1e-3, 3.0, 20.0
    a, cx, cu = amplifier_step("P-865.10", dt)
    state, out = step(amp, 1e-9, AmplifierState(voltage=v0), u, dt)
    assert out.voltage == pytest.approx(a * v0 + (1 - a) * u, rel=1e-12)
    assert 0 < a < 1 and cx + cu == pytest.approx(1.0)      # a mean of v between v0 and v+
    assert amplifier_step("P-865.10", dt, coupling=0) == (a, 1.0, 0.0)


def test_stack_loop_equals_the_loop_stepped_by_hand():
    # one SISO law y -> u (static gain g, Eq. 11: the command of t_k acts from t_(k+1)),
    # amplifier v+ = a v + (1 - a) u, force ch (cx v + cu u) into a sampled structure
    from ctrlfmu.law import DiscreteLaw

    A, B, C, _, dt = _stable_system(4, 2, 2)
    g, ch, amp = 0.3, 2.0, (0.6, 0.7, 0.3)
    law = DiscreteLaw(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[g]], dt,
                      delayed=True)
    Acl, C_force = stack_loop(A, B, C, law, gain=1.5, force_per_volt=ch, amplifier=amp)
    x, u_held, v = RNG.normal(size=4), np.zeros(2), np.zeros(2)
    X = np.concatenate([x, u_held, v])
    for _ in range(20):
        a, cx, cu = amp
        f = ch * (cx * v + cu * u_held)
        np.testing.assert_allclose(C_force @ X, f, rtol=1e-12, atol=1e-14)
        x, v, u_held = A @ x + B @ f, a * v + (1 - a) * u_held, 1.5 * g * (C @ x)
        X = Acl @ X
        # the law's delay state holds its output before the gain
        np.testing.assert_allclose(X, np.concatenate([x, u_held / 1.5, v]), rtol=1e-10,
                                   atol=1e-12)


def test_simulate_with_acs_without_gains_is_the_plain_recursion():
    from acsfmu.pid import AcsConfig, PidGains

    A, B, C, _, dt = _stable_system(4, 5, 6)
    acs = AcsConfig(PidGains(0.0, 0.0, 0.0), sample_time=10 * dt)
    w = RNG.normal(size=(50, 2))
    Y, X = simulate_with_acs(A, B, w, acs, [0, 1, 2], [3, 4, 5], dt, (C, np.eye(4)))
    x = np.zeros(4)
    for k in range(50):
        np.testing.assert_allclose(X[k], x, atol=1e-12)
        x = A @ x + B[:, :2] @ w[k]
    np.testing.assert_allclose(Y, X @ C.T, atol=1e-12)


# -- margins ------------------------------------------------------------------------------
def test_siso_margins_of_a_third_order_lag():
    # L = k / (s + 1)^3: the phase is -180 deg at w = sqrt(3), where |L| = k / 8
    k = 2.0
    f = np.linspace(0.01, 2.0, 200001)
    s = 2j * np.pi * f
    gm, pm, f180, fc = siso_margins(f, k / (s + 1) ** 3)
    assert gm == pytest.approx(-20 * np.log10(k / 8), abs=1e-3)
    assert f180 == pytest.approx(np.sqrt(3) / (2 * np.pi), rel=1e-4)
    wc = np.sqrt(k ** (2 / 3) - 1)                 # |L(j wc)| = 1
    assert fc == pytest.approx(wc / (2 * np.pi), rel=1e-4)
    assert pm == pytest.approx(180 - np.degrees(3 * np.arctan(wc)), abs=1e-2)


def _toy_loop(g):
    # two loops, gains g1 and g2, coupled; stable for small gains
    return np.array([[0.5 + 0.3 * g[0], 0.2 * g[1]], [0.1 * g[0], 0.4 + 0.25 * g[1]]])


@pytest.mark.long   # make test-full
def test_loop_gain_margins_against_a_brute_force_scan():
    g = (0.8, 0.6)

    def stable(gains):
        return spectral_radius(_toy_loop(gains)) < 1.0

    m = loop_gain_margins_db(stable, g, (1, 2), tol=1.0001)
    scan = np.geomspace(1.0, 64.0, 400001)
    for key, scale in (("all", lambda f: (f * g[0], f * g[1])),
                       ("loop1", lambda f: (f * g[0], g[1])),
                       ("loop2", lambda f: (g[0], f * g[1]))):
        first = scan[np.argmax([not stable(scale(f)) for f in scan])]
        assert m[key] == pytest.approx(20 * np.log10(first), abs=0.01)


def test_poles_outside_and_is_stable():
    r, th = 1.02, 2 * np.pi * 50 * 1e-3
    rot = r * np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    A = np.block([[rot, np.zeros((2, 3))], [np.zeros((3, 2)), np.diag([1.0, 0.5, -0.3])]])
    out = poles_outside(A, 1e-3)
    assert len(out) == 1
    assert out[0]["freq_hz"] == pytest.approx(50.0) and out[0]["abs_z"] == pytest.approx(r)
    assert not is_stable(A)
    assert is_stable(without_states(A, [0, 1]))        # the neutral pole at 1 is excepted


def test_band_damping_reads_the_modes_back():
    dt, f, z = 1e-3, np.array([20.0, 80.0]), np.array([0.005, 0.04])
    s = -z * 2 * np.pi * f + 2j * np.pi * f * np.sqrt(1 - z**2)
    lam = np.exp(s * dt)
    A = np.block([[np.array([[l.real, -l.imag], [l.imag, l.real]]) if i == j
                   else np.zeros((2, 2)) for j in range(2)] for i, l in enumerate(lam)])
    d = band_damping(A, A, dt, band=(5.0, 200.0))
    assert d["open_loop_max_damping"] == pytest.approx(0.04, rel=1e-9)
    assert d["closed_loop_min_damping"] == pytest.approx(0.005, rel=1e-9)
    assert d["n_modes_above_1pct"] == 2        # the 4 % mode's pair of poles only
    assert d["closed_loop_most_damped"][0]["f_hz"] == pytest.approx(80.0, rel=1e-9)


def test_best_direction_against_a_scan_of_directions():
    # margin of (k1, k2): the loop is unstable at |k1 - 2 k2| = 4; the score prefers k1
    def margin(k1, k2):
        d = abs(k1 - 2 * k2)
        return np.inf if d == 0 else 20 * np.log10(4 / d)

    def score(k1, k2):
        return k1 + 0.1 * k2

    best = best_direction(margin, score, n_dir=72, required_db=6.0)
    ts = np.linspace(0, 2 * np.pi, 72, endpoint=False)
    brute = max(score(*(10 ** ((margin(np.cos(t), np.sin(t)) - 6) / 20)
                        * np.array([np.cos(t), np.sin(t)])))
                for t in ts if np.isfinite(margin(np.cos(t), np.sin(t))))
    assert best[0] == pytest.approx(brute)
    assert margin(best[1], best[2]) == pytest.approx(6.0)


def test_scaled_to_margins_keeps_every_margin():
    def stable(g):
        return spectral_radius(_toy_loop(g)) < 1.0

    def loops(g):
        return loop_gain_margins_db(stable, g, (1, 2))

    g = scaled_to_margins([1.0, 1.0], lambda g: loops(g)["all"], loops, 6.0)
    assert g is not None and min(loops(g).values()) >= 6.0
    assert g[0] == pytest.approx(g[1])            # the ratio is kept


# -- frf ----------------------------------------------------------------------------------
def test_modal_frequency_response_equals_a_solve_per_frequency():
    A, B, C, D, dt = _stable_system()
    f = np.array([3.0, 47.0, 150.0])
    H = modal_frequency_response(A, B, C, f, dt, D)
    for i, fi in enumerate(f):
        z = np.exp(2j * np.pi * fi * dt)
        ref = C @ np.linalg.solve(z * np.eye(A.shape[0]) - A, B) + D
        np.testing.assert_allclose(H[i], ref, rtol=1e-9)
    P = modal_frequency_response(A, B[:, :2], C[:2], f, dt, pairs=True)
    np.testing.assert_allclose(P, H[:, [0, 1], [0, 1]] - D[[0, 1], [0, 1]], rtol=1e-12)


def test_closed_loop_frf_equals_the_state_space_closed_loop():
    # plant inputs [u (1), d (1)], outputs [s (1), y (2)]; static feedback u = k s
    A, B, C, D, dt = _stable_system(6, 2, 3)
    D[0, 0] = 0.0                      # no algebraic loop
    k = 0.05
    f = np.array([5.0, 60.0])
    G = modal_frequency_response(A, B, C, f, dt, D)
    K = np.full((f.size, 1, 1), k, complex)
    got = closed_loop_frf(G, K, 1, 1, 1)
    # closed loop: u = k (C0 x + D01 d)
    Acl = A + k * np.outer(B[:, 0], C[0])
    Bcl = B[:, 1] + k * B[:, 0] * D[0, 1]
    Ccl = C + k * np.outer(D[:, 0], C[0])
    Dcl = D[:, 1] + k * D[:, 0] * D[0, 1]
    for i, fi in enumerate(f):
        z = np.exp(2j * np.pi * fi * dt)
        ref = Ccl @ np.linalg.solve(z * np.eye(6) - Acl, Bcl) + Dcl
        np.testing.assert_allclose(got[i], ref, rtol=1e-9)


def test_transmissibility_bands_and_bandwidth():
    f = np.arange(1.0, 101.0)
    ratio = np.where((f >= 10) & (f <= 40), 3.0, 0.5)    # isolates from 10 to 40 Hz
    ratio[70] = 0.2                                       # the worst amplification, 71 Hz
    b = transmissibility_bands(f, ratio)
    assert b["below_1_hz"] == [[10.0, 40.0]]
    assert b["max"] == pytest.approx(5.0) and b["max_hz"] == 71.0
    assert isolation_bandwidth(f, ratio, 22.0) == 40.0
    assert isolation_bandwidth(f, ratio, 60.0) is None


# -- bounds -------------------------------------------------------------------------------
def test_harmonic_ceiling_against_lstsq_and_exact_cancellation():
    nh, ny, nu = 3, 4, 2
    Gd = RNG.normal(size=(nh, ny)) + 1j * RNG.normal(size=(nh, ny))
    Gu = RNG.normal(size=(nh, ny, nu)) + 1j * RNG.normal(size=(nh, ny, nu))
    Sd = RNG.normal(size=(nh, nu)) + 1j * RNG.normal(size=(nh, nu))
    Su = RNG.normal(size=(nh, nu, nu)) + 1j * RNG.normal(size=(nh, nu, nu))
    a = np.array([1.0, 0.5, 0.2])
    c = harmonic_ceiling(Gd, Gu, a, Sd, Su)
    best = np.array([Gd[i] + Gu[i] @ np.linalg.lstsq(Gu[i], -Gd[i], rcond=None)[0]
                     for i in range(nh)])
    assert c["optimal"] == pytest.approx(harmonic_reduction_pct(Gd, best, a), abs=1e-10)
    null = np.array([Gd[i] + Gu[i] @ np.linalg.solve(Su[i], -Sd[i]) for i in range(nh)])
    assert c["cancel"] == pytest.approx(harmonic_reduction_pct(Gd, null, a), abs=1e-10)
    assert c["cancel"] <= c["optimal"] + 1e-12        # nothing beats the optimum
    # the reduction by its definition
    red = 100 * (1 - np.sqrt(np.sum(a[:, None]**2 * abs(best)**2)
                             / np.sum(a[:, None]**2 * abs(Gd)**2)))
    assert harmonic_reduction_pct(Gd, best, a) == pytest.approx(red)


def test_best_real_gain_against_a_scan():
    b = RNG.normal(size=5) + 1j * RNG.normal(size=5)
    e = RNG.normal(size=5) + 1j * RNG.normal(size=5)
    k, red = best_real_gain(b, e)
    ks = np.linspace(k - 1.0, k + 1.0, 20001)
    norms = [np.linalg.norm(b + x * e) for x in ks]
    assert ks[int(np.argmin(norms))] == pytest.approx(k, abs=1e-4)
    assert red == pytest.approx(100 * (1 - min(norms) / np.linalg.norm(b)), abs=1e-6)


def test_least_squares_inputs_against_lstsq():
    nf, ny, ni = 4, 3, 5
    G = RNG.normal(size=(nf, ny, ni)) + 1j * RNG.normal(size=(nf, ny, ni))
    Y = RNG.normal(size=(nf, ny)) + 1j * RNG.normal(size=(nf, ny))
    (r0, F0), (r1, F1) = least_squares_inputs(G, Y, [0.0, 0.3])
    scale = np.median([np.trace(g.conj().T @ g).real for g in G]) / ni
    for i in range(nf):
        # rho = 0: the minimum-norm exact solution
        np.testing.assert_allclose(F0[i], np.linalg.lstsq(G[i], -Y[i], rcond=None)[0],
                                   rtol=1e-10)
        # rho > 0: Tikhonov as one stacked least-squares problem
        Gs = np.vstack([G[i], np.sqrt(r1 * scale) * np.eye(ni)])
        Ys = np.concatenate([-Y[i], np.zeros(ni)])
        np.testing.assert_allclose(F1[i], np.linalg.lstsq(Gs, Ys, rcond=None)[0], rtol=1e-9)


def test_record_ceiling_cancels_what_the_inputs_reach():
    # one output driven by two inputs through static gains: exact cancellation is
    # possible (100 %), and the stroke record (the second output of G) is reported
    n = 64
    t = np.arange(n)
    y = np.array([np.sin(2 * np.pi * 3 * t / n)])
    stroke = np.array([np.cos(2 * np.pi * 5 * t / n)])
    G = np.zeros((n // 2 + 1, 2, 2), complex)
    G[:, 0] = [1.0, 0.5]
    G[:, 1] = [0.2, 0.0]
    c = record_ceiling(G, y, [0.0, 1.0], lambda r: np.ptp(r), stroke)
    assert c["exact"]["reduction_pct"][0] == pytest.approx(100.0, abs=1e-9)
    rec = list(least_squares_records(G, y, [0.0], None, stroke))[0]
    assert c["exact"]["others_max"] == pytest.approx(np.abs(rec[2]).max())
    none = record_ceiling(G, y, [0.0, 1.0], lambda r: np.ptp(r), stroke,
                          fits=lambda r: False)
    assert none["best"] == [None]
    with pytest.raises(ValueError, match="DFT grid"):
        list(least_squares_records(G[:-1], y, [0.0]))


# -- the two closed-loop transfers of a scenario --------------------------------------------
@pytest.mark.slow
def test_transfer_from_an_opened_controller_is_the_settled_response(suite_fmus, suite_fmu_dir):
    # an opened controller's output is a source whose held value no period carries over:
    # its row of the period map is zero up to round-off (1e-53), which matrix balancing
    # once scaled by 1e-51 and the steady state did not survive (|H| ~ 1e28)
    import warnings

    from orchestrator.analysis import linearize
    from orchestrator.analysis.fast import FastResponse
    from orchestrator.analysis.spectra import transfer
    from orchestrator.experiments import SCENARIOS
    from orchestrator.experiments.truss_decay import FMUS

    suite_fmus(*FMUS)
    refs = ["structure.los_tip_roll", "structure.los_tip_yaw"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        op = linearize(SCENARIOS / "truss10_closed_loop.toml",
                       fmu_dir=suite_fmu_dir).opened(["ctrl_long"])
    f, n = 20.0, 20000
    # reference: the opened loop driven by a cosine on ctrl_long.u1 for 20 s, settled
    y, _ = op.simulate(n, lambda name, k: (np.cos(2 * np.pi * f * k * op.base) if
                                           name == "ctrl_long" else 0.0)
                       * np.ones(len(op.blocks[name].outputs)), record=refs)
    t = np.arange(n) * op.base
    keep = t > 10.0
    settled = 2 * np.abs((y[keep] * np.exp(-2j * np.pi * f * t[keep])[:, None]).mean(axis=0))
    H = op.frequency_response(["ctrl_long.u1"], refs, [f])[:, 0, 0]
    np.testing.assert_allclose(np.abs(H), settled, rtol=1e-3)
    tr = transfer(FastResponse(op, refs), ["ctrl_long.u1"], refs, [f]).H[:, 0, 0]
    np.testing.assert_allclose(np.abs(tr), settled, rtol=1e-3)


def test_shifted_triangular_solve_against_a_solve_per_frequency():
    """(z_j I - T) x_j = y_j for many z at once against numpy's solve per column, with a
    trailing block of unit eigenvalues solved by least squares (scipy's lstsq, as the
    per-frequency solve did), z = 1 included (singular there: the minimum-norm answer)."""
    import scipy.linalg as la

    from orchestrator.analysis.steady import _UNIT_RCOND, _solve_shifted

    rng = np.random.default_rng(5)
    n, u = 70, 4                   # 66 eigenvalues inside the circle, 4 at 1
    ev = np.r_[0.9 * np.exp(2j * np.pi * rng.random(n - u)), np.ones(u)]
    T = np.triu(rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n)), 1) * 0.3
    T[np.diag_indices(n)] = ev
    z = np.r_[np.exp(2j * np.pi * rng.random(40)), 1.0]
    Y = rng.standard_normal((n, z.size)) + 1j * rng.standard_normal((n, z.size))
    got = _solve_shifted(T, z, Y, n - u)
    for j, zj in enumerate(z):
        A = zj * np.eye(n) - T
        if zj == 1.0:
            tail = la.lstsq(A[-u:, -u:], Y[-u:, j], cond=_UNIT_RCOND)[0]
            head = np.linalg.solve(A[:-u, :-u], Y[:-u, j] - A[:-u, -u:] @ tail)
            want = np.r_[head, tail]
        else:
            want = np.linalg.solve(A, Y[:, j])
        assert np.max(np.abs(got[:, j] - want)) <= 1e-10 * np.max(np.abs(want)), j


def test_map_threads_keeps_the_order_and_the_values():
    """Analyses side by side in threads (one BLAS thread each): the results come back in
    the order of the items and equal the same calls in this thread to round-off."""
    from orchestrator.analysis._threads import map_threads

    rng = np.random.default_rng(2)
    mats = [rng.standard_normal((300, 300)) for _ in range(5)]

    def work(i):
        return i, np.linalg.eigvals(mats[i] @ mats[i].T).real.max()

    got = map_threads(work, range(5), workers=2)
    assert [i for i, _ in got] == list(range(5))
    for i, top in got:
        want = work(i)[1]
        assert abs(top - want) <= 1e-10 * abs(want)
    assert map_threads(work, [3], workers=4) == [work(3)]
