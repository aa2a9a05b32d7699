"""Discrete law of Eq. (11): equivalence with python-control, limits, activation, files."""

import math
from dataclasses import replace

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctrlfmu.analysis import frequency_response, to_statespace
from ctrlfmu.designs import DESIGNS, design
from ctrlfmu.law import (
    DimensionError,
    DiscreteLaw,
    LawFileError,
    backcalculation_gain,
    initial_state,
    load_law,
    output,
    save_law,
    simulate,
    step,
)


def random_law(seed, n=4, n_in=2, n_out=3, delayed=True, dt=1e-3):
    """Stable random MIMO law (spectral radius 0.9), seeded."""
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((n, n))
    a *= 0.9 / np.max(np.abs(np.linalg.eigvals(a)))
    return DiscreteLaw(a, rng.standard_normal((n, n_in)), rng.standard_normal((n_out, n)),
                       rng.standard_normal((n_out, n_in)), dt, delayed=delayed)


def unlimited(law):
    return law.with_limits(-np.inf, np.inf)


LAWS = [pytest.param(unlimited(design(n)), id=n) for n in sorted(DESIGNS)] + [
    pytest.param(random_law(1), id="random_mimo_delayed"),
    pytest.param(random_law(2, delayed=False), id="random_mimo_direct"),
]


@pytest.mark.parametrize("law", LAWS)
def test_forced_response_equals_python_control(law):
    # Reference: control.forced_response of the same discrete (A, B, C, D).  Eq. (11)
    # applies C x(k) + D y(k) one sample late: u_law[k] = y_ref[k-1], u_law[0] = 0.
    rng = np.random.default_rng(7)
    n_samples = 400
    y = rng.standard_normal((n_samples, law.n_inputs))
    u, _ = simulate(law, y)
    ref = control.ss(law.A, law.B, law.C, law.D, law.dt)
    t = np.arange(n_samples) * law.dt
    y_ref = np.atleast_2d(control.forced_response(ref, t, y.T).outputs).T.reshape(n_samples, -1)
    scale = np.max(np.abs(y_ref))
    if law.delayed:
        np.testing.assert_array_equal(u[0], 0.0)
        np.testing.assert_allclose(u[1:], y_ref[:-1], rtol=0, atol=1e-12 * scale)
    else:
        np.testing.assert_allclose(u, y_ref, rtol=0, atol=1e-12 * scale)
    # The delay-augmented system of to_statespace reproduces the applied command directly.
    y_aug = control.forced_response(to_statespace(law), t, y.T).outputs
    np.testing.assert_allclose(u, np.atleast_2d(y_aug).T.reshape(n_samples, -1),
                               rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("name", ["truss10_strain_diag", "testbed_isolation"])
def test_step_response_equals_python_control(name):
    law = unlimited(design(name))
    n_samples = 300
    t = np.arange(n_samples) * law.dt
    ref = control.step_response(control.ss(law.A, law.B, law.C, law.D, law.dt), t, input=0)
    y = np.zeros((n_samples, law.n_inputs))
    y[:, 0] = 1.0
    u, _ = simulate(law, y)
    expected = np.ravel(ref.outputs)
    np.testing.assert_allclose(u[1:, 0], expected[:-1], rtol=0,
                               atol=1e-12 * np.max(np.abs(expected)))


def test_frequency_response_matches_python_control():
    law = random_law(3)
    f = np.array([0.5, 10.0, 123.0, 400.0])
    h = frequency_response(law, f)
    ref = to_statespace(law)(np.exp(2j * np.pi * f * law.dt))
    np.testing.assert_allclose(h, ref, rtol=1e-10)
    # the one-sample delay is a pure phase factor
    h0 = frequency_response(law, f, include_delay=False)
    np.testing.assert_allclose(h * np.exp(2j * np.pi * f * law.dt), h0, rtol=1e-12)


def test_delayed_output_is_independent_of_current_input_and_direct_is_not():
    delayed, direct = random_law(4), random_law(4, delayed=False)
    s = step(delayed, initial_state(delayed), [1.0, -2.0])[0]
    np.testing.assert_array_equal(output(delayed, s, [5.0, 5.0]), output(delayed, s, [0.0, 0.0]))
    assert not delayed.feedthrough.any()
    np.testing.assert_array_equal(direct.feedthrough, direct.D != 0)
    s = initial_state(direct)
    np.testing.assert_allclose(output(direct, s, [1.0, 0.0]), direct.D[:, 0], rtol=1e-15)


def test_shape_errors_name_matrix_and_expected_shape():
    with pytest.raises(DimensionError, match=r"^controller matrix B has shape \(3, 2\); "
                       r"expected \(3, 1\) for 3 states and 1 input$"):
        DiscreteLaw(np.eye(3), np.ones((3, 2)), np.ones((1, 3)), np.zeros((1, 1)), 0.004)
    with pytest.raises(DimensionError, match=r"controller matrix C has shape \(1, 2\); "
                       r"expected \(1, 3\) for 1 output and 3 states"):
        DiscreteLaw(np.eye(3), np.ones((3, 1)), np.ones((1, 2)), np.zeros((1, 1)), 0.004)
    with pytest.raises(DimensionError, match="A has shape"):
        DiscreteLaw(np.ones((2, 3)), np.ones((2, 1)), np.ones((1, 2)), np.zeros((1, 1)), 0.004)
    with pytest.raises(DimensionError, match=r"measurement y has shape \(3,\); expected \(2,\)"):
        law = random_law(5)
        step(law, initial_state(law), [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="dt must be a positive"):
        DiscreteLaw(np.eye(1), np.ones((1, 1)), np.ones((1, 1)), np.zeros((1, 1)), 0.0)
    with pytest.raises(ValueError, match="u_min > u_max"):
        DiscreteLaw(np.eye(1), np.ones((1, 1)), np.ones((1, 1)), np.zeros((1, 1)), 1.0,
                    u_min=1.0, u_max=-1.0)


def test_law_arrays_are_read_only_copies():
    a = np.eye(2)
    law = DiscreteLaw(a, np.ones((2, 1)), np.ones((1, 2)), np.zeros((1, 1)), 0.01)
    a[0, 0] = 5.0
    assert law.A[0, 0] == 1.0
    with pytest.raises(ValueError):
        law.A[0, 0] = 3.0


def integrator(delayed=True, **kw):
    """u = sum of y dt, limited to +/-0.5: the textbook windup case."""
    return DiscreteLaw([[1.0]], [[0.1]], [[1.0]], [[0.0]], 0.1, delayed=delayed,
                       u_min=-0.5, u_max=0.5, **kw)


def samples_until_unsaturated(law):
    y = np.r_[np.ones(100), -np.ones(100)]
    u, _ = simulate(law, y)
    assert np.all(u <= 0.5) and np.all(u >= -0.5)
    after = u[100:, 0] < 0.5 - 1e-12
    # argmax of an all-False array is 0: a law that never leaves the limit must not
    # look like one that leaves it at once
    return int(np.argmax(after)) if after.any() else len(after)


def test_limits_and_backcalculation_antiwindup():
    plain = integrator()
    # Without anti-windup the state winds up to 10 while u sticks at 0.5 and needs
    # 95 samples of y = -1 to come back below the limit.
    assert samples_until_unsaturated(plain) > 90
    # Back-calculation placing A - L C at 0 keeps x = u_sat: the output leaves the limit
    # after the one-sample delay plus one sample.
    aw = replace(plain, aw_gain=backcalculation_gain(plain, [0.0]))
    np.testing.assert_allclose(aw.aw_gain, [[1.0]], rtol=1e-12)
    assert samples_until_unsaturated(aw) <= 2
    # Unsaturated, anti-windup changes nothing (u - v == 0 exactly).
    y = 0.1 * np.sin(np.arange(50))
    np.testing.assert_array_equal(simulate(plain, y)[0], simulate(aw, y)[0])


def test_backcalculation_sign_on_a_hand_computed_saturated_step():
    # Scalar delayed law x(k+1) = x + 1.0*y + L (u - v), v = x, u = clip(v, -1, 1), L = 0.5,
    # fed y = 2, 2, 2, 2, -2, -2 (hand-computed; u[k] is the command held at t_k):
    #   k  y   x(k)    v = x    u(k+1) = clip(v)   u - v     x(k+1) = x + y + 0.5 (u - v)
    #   0  2   0       0        0                  0         0 + 2 + 0          = 2
    #   1  2   2       2        1                  -1        2 + 2 - 0.5        = 3.5
    #   2  2   3.5     3.5      1                  -2.5      3.5 + 2 - 1.25     = 4.25
    #   3  2   4.25    4.25     1                  -3.25     4.25 + 2 - 1.625   = 4.625
    #   4  -2  4.625   4.625    1                  -3.625    4.625 - 2 - 1.8125 = 0.8125
    #   5  -2  0.8125  0.8125   0.8125             0         0.8125 - 2 + 0     = -1.1875
    # While saturated, x - 5 halves every sample (fixed point x + 2 + 0.5 (1 - x) = x at
    # x = 5), and the output leaves the limit on the second sample of y = -2.  Without
    # anti-windup x would be 0, 2, 4, 6, 8, 6, 4 (u still at the limit); with the sign of
    # the correction flipped, x(2) = 2 + 2 + 0.5 = 4.5 and the state runs away.
    law = DiscreteLaw([[1.0]], [[1.0]], [[1.0]], [[0.0]], 0.1, u_min=-1.0, u_max=1.0,
                      aw_gain=[[0.5]])
    y = [2.0, 2.0, 2.0, 2.0, -2.0, -2.0]
    state = initial_state(law)
    xs = [state.x[0]]
    for yk in y:
        state, _ = step(law, state, yk)
        xs.append(state.x[0])
    np.testing.assert_allclose(xs, [0.0, 2.0, 3.5, 4.25, 4.625, 0.8125, -1.1875],
                               rtol=0, atol=1e-15)
    u, last = simulate(law, y)
    np.testing.assert_allclose(u[:, 0], [0.0, 0.0, 1.0, 1.0, 1.0, 1.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(last.u, [0.8125], rtol=0, atol=1e-15)  # off the limit
    np.testing.assert_allclose(step(law, state, 0.0)[1], [-1.0])  # clip(-1.1875)


@pytest.mark.parametrize("law", [design("truss10_strain_long"), design("eos_isolation"),
                                 random_law(8)])
def test_default_backcalculation_gain_places_poles(law):
    gain = backcalculation_gain(law)
    assert gain.shape == (law.n_states, law.n_outputs)
    eig = np.sort(np.linalg.eigvals(law.A - gain @ law.C).real)
    np.testing.assert_allclose(eig, np.linspace(0.2, 0.5, law.n_states), atol=1e-9)


def test_backcalculation_gain_reports_unplaceable_poles():
    # Moving six poles at z ~ 0.999 to 0.2..0.5 through one output is ill-conditioned.
    with pytest.raises(ValueError, match="cannot place the anti-windup poles"):
        backcalculation_gain(design("testbed_isolation"))


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=60),
       st.floats(-2.0, 0.0), st.floats(0.0, 2.0))
def test_output_never_exceeds_limits(ys, lo, hi):
    law = design("truss10_strain_diag").with_limits(lo, hi)
    u, _ = simulate(law, np.asarray(ys) * 1e-6)
    assert np.all(u >= lo) and np.all(u <= hi)


def test_with_gain_scales_output_linearly():
    law = unlimited(design("eos_isolation"))
    y = np.random.default_rng(0).standard_normal(80) * 1e-5
    np.testing.assert_allclose(simulate(law.with_gain(-2.5), y)[0], -2.5 * simulate(law, y)[0],
                               rtol=1e-12, atol=1e-12)


def test_activation_time_and_enable_reset_state():
    base = unlimited(design("truss10_strain_diag"))
    dt = base.dt
    delayed = base.with_t_on(0.1)     # 25 samples at 250 Hz
    assert delayed.first_active_sample == 25
    y = np.ones(60) * 1e-6
    u, _ = simulate(delayed, y)
    # Delayed form: nothing before t_on, and the first command appears one sample later.
    np.testing.assert_array_equal(u[:26], 0.0)
    assert u[26, 0] != 0.0
    # Activated at sample 25 from a zero state, the response is the t_on = 0 response
    # shifted by 25 samples.
    u0, _ = simulate(base, y)
    np.testing.assert_allclose(u[25:], u0[:35], rtol=1e-13)
    # Disabling resets the state, so re-enabling restarts from rest.
    enable = np.r_[np.ones(30, bool), np.zeros(5, bool), np.ones(25, bool)]
    u_en, state = simulate(base, y, enable)
    np.testing.assert_array_equal(u_en[31:36], 0.0)
    np.testing.assert_allclose(u_en[35:], u0[:25], rtol=1e-13)
    assert state.k == 60 and dt == pytest.approx(0.004)


def test_first_active_sample_is_robust_to_rounding():
    law = DiscreteLaw([[0.0]], [[1.0]], [[1.0]], [[0.0]], 0.001, t_on=2.4)
    assert law.first_active_sample == 2400      # 2.4 / 0.001 = 2399.9999999999995


@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_npz_round_trip_is_exact(tmp_path, name):
    law = design(name).with_t_on(1.25)
    path = save_law(law, tmp_path / name)
    assert path.suffix == ".npz"
    back = load_law(path)
    for attr in ("A", "B", "C", "D", "aw_gain", "u_min", "u_max"):
        np.testing.assert_array_equal(getattr(back, attr), getattr(law, attr))
    for attr in ("dt", "t_on", "delayed", "name", "inputs", "outputs", "input_units",
                 "output_units", "description"):
        assert getattr(back, attr) == getattr(law, attr)
    y = np.random.default_rng(1).standard_normal((50, law.n_inputs))
    np.testing.assert_array_equal(simulate(back, y)[0], simulate(law, y)[0])


def test_load_rejects_foreign_npz(tmp_path):
    np.savez(tmp_path / "x.npz", A=np.eye(2))
    with pytest.raises(LawFileError, match="not a control law file"):
        load_law(tmp_path / "x.npz")


def test_step_is_pure():
    law = random_law(6)
    s0 = initial_state(law)
    s1, u1 = step(law, s0, [1.0, 2.0])
    s1b, u1b = step(law, s0, [1.0, 2.0])
    np.testing.assert_array_equal(u1, u1b)
    np.testing.assert_array_equal(s1.x, s1b.x)
    np.testing.assert_array_equal(s0.x, 0.0)
    assert s0.k == 0 and s1.k == 1 and math.isfinite(u1.sum())
