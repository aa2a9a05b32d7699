"""Loop margins (orchestrator.analysis.loops) against closed forms and python-control."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from orchestrator.analysis.loops import BrokenLoop, disk_to_gain_phase, margins_of


def _loop(Phi, Gam, R, dt=1.0):
    Phi, Gam, R = (np.atleast_2d(np.asarray(v, float)) for v in (Phi, Gam, R))
    return BrokenLoop(Phi, Gam, R, np.zeros((R.shape[0], Gam.shape[1])), dt, ("c.u",))


A_, B_, K_ = 0.6, 1.0, 0.7   # crossover exists: 1 - a < K b < 1


def _first_order():
    # plant x+ = a x + b u, y = x; law u[n+1] = -K y[n] (one-sample delay).  State
    # [x, u]: broken at u, T(z) = -K b / (z (z - a)); with a factor k on the command the
    # closed loop is z^2 - a z + k K b.
    return _loop([[A_, 0.0], [-K_, 0.0]], [[B_], [0.0]], [[0.0, 1.0]])


def test_first_order_plant_one_sample_delay_closed_forms():
    a, b, K = A_, B_, K_
    m = margins_of(_first_order(), "g").loops[0]
    assert m.stable
    # complex pair on the unit circle at k K b = 1
    np.testing.assert_allclose(m.gain_up_db, 20 * math.log10(1.0 / (K * b)), atol=0.01)
    # |T| = 1 where |e^{jw} - a| = K b; phase margin 180 + arg L there, L = -T
    w = math.acos((1 + a * a - (K * b) ** 2) / (2 * a))
    L = K * b / (np.exp(1j * w) * (np.exp(1j * w) - a))
    pm = math.degrees(np.angle(-L))
    np.testing.assert_allclose(m.phase_deg, abs(pm), atol=0.2)
    np.testing.assert_allclose(m.crossovers_hz[0], w / (2 * math.pi), rtol=2e-3)


def test_sign_flip_lower_margin_closed_form():
    # for k < 0 a real root reaches z = 1 at 1 - a + k K b = 0
    from orchestrator.analysis.loops import _factor_boundary

    loop = _first_order()
    m = margins_of(loop, "g").loops[0]
    assert math.isinf(m.gain_down_db)    # stable down to zero gain and through it
    k = _factor_boundary(lambda c: loop.stable([c]), "down")
    np.testing.assert_allclose(k, -(1 - A_) / (K_ * B_), rtol=2e-3)


def test_sampled_mode_critical_gain_against_polynomial_roots():
    # a lightly damped mode sampled with ZOH, rate feedback with a one-sample delay
    wn, zeta, dt, K = 2 * math.pi * 3.0, 0.01, 0.01, 2.0
    Ac = np.array([[0.0, 1.0], [-wn**2, -2 * zeta * wn]])
    sysd = control.c2d(control.ss(Ac, [[0.0], [1.0]], [[0.0, 1.0]], 0.0), dt)
    Ad, Bd, Cd = (np.asarray(v) for v in (sysd.A, sysd.B, sysd.C))
    Phi = np.block([[Ad, np.zeros((2, 1))], [-K * Cd, np.zeros((1, 1))]])
    Gam = np.vstack([Bd, [[0.0]]])
    R = np.array([[0.0, 0.0, 1.0]])
    m = margins_of(_loop(Phi, Gam, R, dt), "g").loops[0]

    def stable(k):   # independent: roots of the closed loop's characteristic polynomial
        A = np.block([[Ad, Bd], [-k * K * Cd, np.zeros((1, 1))]])
        return np.max(np.abs(np.roots(np.poly(A)))) < 1

    lo, hi = 1.0, 1e4
    assert stable(lo) and not stable(hi)
    while hi / lo > 1.0001:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    np.testing.assert_allclose(m.gain_up_db, 20 * math.log10(lo), atol=0.01)


def test_disk_margin_matches_python_control():
    # discrete loop L(z) = k (z + 0.5) / ((z - 1)(z - 0.6)) z^-1 in negative feedback
    dt = 0.1
    L = control.tf([0.08, 0.04], [1.0, -1.6, 0.6, 0.0], dt)
    assert np.all(np.abs(control.feedback(L, 1).poles()) < 1)   # stable: disk margin defined
    ss = control.ss(L)
    A, B, C = np.asarray(ss.A), np.asarray(ss.B), np.asarray(ss.C)
    # broken loop: X+ = A X + B e, y = -C X (T = -L)
    loop = BrokenLoop(A, B, -C, np.zeros((1, 1)), dt, ("c.u",))
    m = margins_of(loop, "g").loops[0]
    omega = np.linspace(1e-3, math.pi / dt * 0.999, 20000)
    dm, dgm, dpm = control.disk_margins(L, omega, skew=0.0)
    np.testing.assert_allclose(m.disk_alpha, dm, rtol=2e-3)
    g, p = disk_to_gain_phase(m.disk_alpha)
    np.testing.assert_allclose(p, dpm, rtol=2e-3)
    # a factor inside the disk keeps the loop stable, one just outside its gain does not
    hi = (2 + m.disk_alpha) / (2 - m.disk_alpha)
    assert loop.stable([hi * 0.999])
    assert m.gain_up_db >= 20 * math.log10(hi) - 1e-6


@pytest.mark.parametrize("alpha", [0.0, 0.5, 1.9, 2.0])
def test_disk_to_gain_phase(alpha):
    g, p = disk_to_gain_phase(alpha)
    if alpha == 0:
        assert (g, p) == (0.0, 0.0)
    elif alpha >= 2:
        assert math.isinf(g)
    else:
        np.testing.assert_allclose(10 ** (g / 20), (2 + alpha) / (2 - alpha))
        np.testing.assert_allclose(p, math.degrees(2 * math.atan(alpha / 2)))
