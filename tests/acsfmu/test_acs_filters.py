"""ACS filters: Tustin prewarped biquads, the filtered law, its linear block, refusals.

References: ``scipy.signal.bilinear`` at the sampling rate ``K / 2`` with
``K = w / tan(w T / 2)`` (Tustin prewarped at ``w``, Franklin, Powell & Workman,
*Digital Control of Dynamic Systems*, 3rd ed., Sec. 6.3.1), ``scipy.signal.lfilter``
for the filters run over a sequence, and a verbatim copy of the unfiltered law as it
was before the filters came.
"""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy import signal

from acsfmu.design import pid_gains_for
from acsfmu.filters import AcsFilters, biquad_step, lowpass_biquad, notch_biquad
from acsfmu.pid import AcsConfig, AcsConfigError, AcsState, PidGains, acs_advance, \
    acs_outputs, initial_state
from acsfmu.slave import AcsSlave

T = 0.1
INERTIA = (7600.0, 36000.0, 36000.0)
GAINS = PidGains(*(list(g) for g in zip(*(pid_gains_for(j, 0.1, 50.0, T) for j in INERTIA))))
#: every filter on, all different, none saturating
FILTERS = dict(notch_hz=[1.3, 0.9, 2.2], notch_zeta_num=[0.05, 0.1, 0.02],
               notch_zeta_den=[0.5, 0.3, 0.7], lowpass_hz=[0.8, 2.0, 3.0],
               lowpass_zeta=[0.7, 0.5, 0.9], antialias_hz=2.5, antialias_zeta=0.6)


def _scipy_prewarped(b_s, a_s, f, T):
    """Tustin prewarped at w = 2 pi f through scipy's bilinear (its fs = K / 2)."""
    w = 2 * np.pi * f
    b, a = signal.bilinear(b_s, a_s, fs=w / (2 * np.tan(w * T / 2)))
    b, a = np.pad(b, (3 - len(b), 0)), np.asarray(a)
    return np.concatenate([b / a[0], a[1:] / a[0]])


def _response(coef, f, T):
    z1 = np.exp(-2j * np.pi * f * T)   # z^-1 on the unit circle at f
    b0, b1, b2, a1, a2 = coef
    return (b0 + b1 * z1 + b2 * z1**2) / (1 + a1 * z1 + a2 * z1**2)


@pytest.mark.parametrize("f,zn,zd,T", [(1.3, 0.05, 0.5, 0.1), (4.5, 0.0 + 1e-3, 0.2, 0.1),
                                       (120.0, 0.1, 0.7, 1e-3), (0.01, 0.02, 1.5, 0.1)])
def test_notch_coefficients_match_scipy_and_the_depth_is_exact(f, zn, zd, T):
    w = 2 * np.pi * f
    coef = notch_biquad(f, zn, zd, T)
    ref = _scipy_prewarped([1.0, 2 * zn * w, w * w], [1.0, 2 * zd * w, w * w], f, T)
    np.testing.assert_allclose(coef, ref, rtol=1e-10, atol=1e-12)
    # prewarping maps s = j w onto z = e^{j w T}: the depth at the centre is zn / zd
    np.testing.assert_allclose(_response(coef, f, T), zn / zd, rtol=1e-9, atol=1e-12)
    assert _response(coef, 0.0, T) == pytest.approx(1.0, abs=1e-12)   # unit DC gain


@pytest.mark.parametrize("f,zeta,T", [(0.8, 0.7, 0.1), (4.9, 0.3, 0.1), (45.0, 0.5, 1e-3)])
def test_lowpass_coefficients_match_scipy_and_the_corner_gain_is_exact(f, zeta, T):
    w = 2 * np.pi * f
    coef = lowpass_biquad(f, zeta, T)
    np.testing.assert_allclose(coef, _scipy_prewarped([w * w], [1.0, 2 * zeta * w, w * w], f, T),
                               rtol=1e-10, atol=1e-12)
    # H(j w) = 1 / (2 j zeta) at the corner, kept exactly by the prewarping
    np.testing.assert_allclose(_response(coef, f, T), 1 / (2j * zeta), rtol=1e-9)
    assert _response(coef, 0.0, T) == pytest.approx(1.0, abs=1e-12)


def test_biquad_step_is_scipys_lfilter():
    coef = notch_biquad(1.3, 0.05, 0.5, T)
    x = np.random.default_rng(2).standard_normal(300)
    s, y = np.zeros(2), []
    for v in x:
        out, s = biquad_step(coef, v, s)
        y.append(out)
    np.testing.assert_allclose(y, signal.lfilter(coef[:3], [1.0, *coef[3:]], x),
                               rtol=0, atol=1e-13 * np.abs(x).max())


def _config(torque_limit=1e9, momentum_limit=1e9, **filters):
    f = AcsFilters(T, **filters) if filters else None
    return AcsConfig(GAINS, sample_time=T, torque_limit=torque_limit,
                     momentum_limit=momentum_limit, filters=f)


def _run(cfg, u, h=T, momentum0=0.0, advance=acs_advance):
    state, y = initial_state(cfg, 0.0, momentum0), []
    for k in range(u.shape[0]):
        state = advance(cfg, replace(state, time=k * h), h, u[k, :3], u[k, 3:])
        y.append(np.concatenate(acs_outputs(cfg, state)))
    return np.array(y), state


def _inputs(n=300, seed=5):
    rng = np.random.default_rng(seed)
    return np.hstack([1e-3 * np.cumsum(rng.normal(size=(n, 3)), axis=0) / 10,
                      1e-4 * rng.normal(size=(n, 3))])


def test_torque_filters_are_the_biquads_on_the_unfiltered_command():
    """No saturation: the integrator never sees the filters, so the filtered torque is
    lfilter(low-pass, lfilter(notch, unfiltered torque)) on every axis."""
    u = _inputs()
    plain, _ = _run(_config(), u)
    filt = {k: v for k, v in FILTERS.items() if not k.startswith("antialias")}
    y, _ = _run(_config(**filt), u)
    for i in range(3):
        n = notch_biquad(FILTERS["notch_hz"][i], FILTERS["notch_zeta_num"][i],
                         FILTERS["notch_zeta_den"][i], T)
        lp = lowpass_biquad(FILTERS["lowpass_hz"][i], FILTERS["lowpass_zeta"][i], T)
        ref = signal.lfilter(lp[:3], [1, *lp[3:]],
                             signal.lfilter(n[:3], [1, *n[3:]], plain[:, i]))
        np.testing.assert_allclose(y[:, i], ref, rtol=0, atol=1e-12 * np.abs(ref).max())
        assert np.abs(y[:, i] - plain[:, i]).max() > 1e-3 * np.abs(plain[:, i]).max()


def test_antialias_filter_is_the_biquad_on_each_sampled_input():
    u = _inputs()
    aa = lowpass_biquad(2.5, 0.6, T)
    y, _ = _run(_config(antialias_hz=2.5, antialias_zeta=0.6), u)
    ref, _ = _run(_config(), signal.lfilter(aa[:3], [1, *aa[3:]], u, axis=0))
    peak = np.abs(ref).max(axis=0)
    np.testing.assert_allclose(y / peak, ref / peak, rtol=0, atol=1e-12)


def test_filter_states_survive_the_state_array_and_sub_stepping():
    cfg, u = _config(**FILTERS), _inputs(60)
    y1, s1 = _run(cfg, u)
    y2, s2 = _run(cfg, np.repeat(u, 4, axis=0), h=T / 4)   # same held inputs, 4 steps
    peak = np.abs(y1).max(axis=0)   # the wheel momentum sums 4x more round-off terms
    np.testing.assert_allclose(y2[3::4] / peak, y1 / peak, rtol=0, atol=1e-12)
    assert np.abs(s1.notch).max() > 0 and np.abs(s1.antialias).max() > 0
    again = AcsState.from_array(s1.as_array())
    np.testing.assert_array_equal(again.as_array(), s1.as_array())
    np.testing.assert_array_equal(again.lowpass, s1.lowpass)


# ------------------------------------------------------------- defaults leave the law alone

def _old_pid_command(config, integral, attitude, rate, momentum_next):
    """acsfmu.pid.pid_command before the filters (verbatim)."""
    g, T = config.gains, config.sample_time
    e = np.asarray(attitude, dtype=float) - config.reference
    v = -(g.kp * e + g.kd * np.asarray(rate, dtype=float) + g.ki * integral)
    hmax = config.momentum_limit
    u = np.clip(v, (momentum_next - hmax) / T, (momentum_next + hmax) / T)
    u = np.clip(u, -config.torque_limit, config.torque_limit)
    saturated = u != v
    dv = -g.ki * T * e
    winds_up = saturated & (np.sign(dv) == np.sign(v - u)) & config.anti_windup
    return u, np.where(winds_up, integral, integral + T * e)


def _old_advance(config, state, h, attitude, rate):
    """acsfmu.pid.acs_advance before the filters (verbatim but for the names)."""
    T = config.sample_time
    tol = 1e-6 * T
    t, t_end = state.time, state.time + h
    z = state.integral.copy()
    u_act = state.torque_active.copy()
    u_pend = state.torque_pending.copy()
    hw = state.momentum.copy()
    n, activated = state.next_sample, state.activated
    if n * T < t - tol:
        n = math.ceil(t / T - 1e-6)
    cur = t
    while n * T < t_end - tol:
        tau = max(n * T, cur)
        hw -= u_act * (tau - cur)
        cur = tau
        if activated < n:
            u_act, activated = u_pend, n
        u_pend, z = _old_pid_command(config, z, attitude, rate, hw - u_act * T)
        n += 1
    hw -= u_act * (t_end - cur)
    if abs(t_end - n * T) <= tol and activated < n:
        u_act, activated = u_pend, n
    return AcsState(z, u_act, u_pend, hw, n, activated, float(t_end))


def test_with_every_filter_off_the_law_is_bit_for_bit_the_old_one():
    """Torque and momentum limits active (the anti-windup path runs), filters off."""
    u = 30 * _inputs(400)
    cfg = _config(torque_limit=0.4, momentum_limit=3.0)
    y, _ = _run(cfg, u, momentum0=2.5)
    assert np.abs(y[:, :3]).max() == 0.4                        # it saturated
    for h in (T, 0.03, 0.25):   # any communication step
        y, _ = _run(cfg, u, h=h, momentum0=2.5)
        np.testing.assert_array_equal(y, _run(cfg, u, h=h, momentum0=2.5,
                                              advance=_old_advance)[0])
    y, _ = _run(cfg, u, momentum0=2.5)
    off = _config(torque_limit=0.4, momentum_limit=3.0, notch_hz=0.0, antialias_hz=0.0)
    np.testing.assert_array_equal(_run(off, u, momentum0=2.5)[0], y)


def test_per_axis_bandwidth_overrides_the_common_one():
    s = AcsSlave(instance_name="a")
    s.bandwidth_y = 0.05
    g = s.config().gains
    for i, (j, bw) in enumerate(zip(INERTIA, (0.1, 0.05, 0.1))):
        np.testing.assert_array_equal([g.kp[i], g.ki[i], g.kd[i]],
                                      pid_gains_for(j, bw, 50.0, T))


# -------------------------------------------------------------------------- linear block

def _block(slave):
    from orchestrator.analysis.blocks import _acs_block

    return _acs_block(slave, "acs", 1, slave.sample_time, np.zeros(6, bool))


def test_linear_block_is_the_filtered_law():
    s = AcsSlave(instance_name="acs")
    s.torque_limit, s.momentum_limit, s.bandwidth_z = 1e9, 1e9, 0.07
    for name, value in FILTERS.items():
        for axis, v in zip("xyz", np.broadcast_to(value, (3,))):
            setattr(s, name if name.startswith("antialias") else f"{name}_{axis}", float(v))
    b, cfg, u = _block(s), s.config(), _inputs()
    assert b.n == 3 + 2 * (6 + 3 + 3) + 3 and b.model is cfg.filters
    y, _ = _run(cfg, u)
    x, yb = np.zeros(b.n), []
    for k in range(u.shape[0]):
        x = b.A @ x + b.B @ u[k]
        yb.append(b.C @ x + b.D @ u[k])
    yb = np.array(yb)[:, :3]
    np.testing.assert_allclose(yb, y[:, :3], rtol=0, atol=1e-12 * np.abs(y[:, :3]).max())


def test_linear_block_with_filters_off_is_the_old_block():
    s = AcsSlave(instance_name="acs")
    b, g = _block(s), s.config().gains
    A, B = np.zeros((6, 6)), np.zeros((6, 6))     # the block before the filters
    A[:3, :3], A[3:, :3] = np.eye(3), -np.diag(g.ki)
    B[:3, :3], B[3:, :3], B[3:, 3:] = T * np.eye(3), -np.diag(g.kp), -np.diag(g.kd)
    C = np.zeros((6, 6))
    C[:3, 3:] = np.eye(3)
    for new, old in ((b.A, A), (b.B, B), (b.C, C), (b.D, np.zeros((6, 6)))):
        np.testing.assert_array_equal(new, old)


# ------------------------------------------------------------------------------ refusals

@pytest.mark.parametrize("changes,message", [
    ({"notch_hz": [0.0, 6.0, 0.0]}, "ACS filters: notch_hz_y = 6 Hz is at or above the "
     "Nyquist frequency 5 Hz of sample time 0.1 s"),
    ({"lowpass_hz": 5.0}, "ACS filters: lowpass_hz_x = 5 Hz is at or above the Nyquist "
     "frequency 5 Hz of sample time 0.1 s"),
    ({"antialias_hz": -1.0}, "ACS filters: antialias_hz = -1 Hz is negative; expected 0 "
     "(off) or a corner below the Nyquist frequency 5 Hz"),
    ({"lowpass_zeta": [0.7, 0.7, 0.0]}, "ACS filters: lowpass_zeta_z = 0 is not a positive "
     "damping ratio (filters sampled below the Nyquist frequency 5 Hz)"),
    ({"notch_zeta_den": -0.5}, "ACS filters: notch_zeta_den_x = -0.5 is not a positive "
     "damping ratio (filters sampled below the Nyquist frequency 5 Hz)"),
])
def test_a_filter_it_cannot_sample_is_refused_in_one_sentence(changes, message):
    with pytest.raises(AcsConfigError) as info:
        AcsFilters(T, **changes)
    assert str(info.value) == message


def test_the_slave_refuses_a_filter_above_nyquist_before_any_step():
    s = AcsSlave(instance_name="acs1")
    s.sample_time, s.notch_hz_z = 0.01, 60.0
    before = s.x.copy()
    with pytest.raises(AcsConfigError) as info:
        s.exit_initialization_mode()
    assert str(info.value) == ("ACS instance 'acs1': ACS filters: notch_hz_z = 60 Hz is at or "
                               "above the Nyquist frequency 50 Hz of sample time 0.01 s")
    np.testing.assert_array_equal(s.x, before)       # nothing was computed
    assert math.isfinite(s.x[0])
