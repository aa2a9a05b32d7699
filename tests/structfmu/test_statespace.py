"""First-order form, FRFs and exact discretisation."""

import control
import numpy as np
import pytest
from scipy.signal import cont2discrete

from structfmu.discrete import discretize, modal_zoh, output, simulate, step
from structfmu.reduced import ReducedModel
from structfmu.statespace import first_order, frf, full_frf, to_statespace


def small_model(rigid=True, overdamped=True):
    rng = np.random.default_rng(7)
    omega = np.array([0.0 if rigid else 3.0, 12.0, 40.0, 95.0])
    c = np.array([0.0, 0.3, 2 * 40.0 * 1.5 if overdamped else 1.0, 2.0])
    Koo = np.array([[9e6, 1e6], [1e6, 4e6]])
    Doo = 1e-4 * Koo + 5.0 * np.eye(2)
    return ReducedModel(omega=omega, modal_damping=c, B_e=rng.normal(size=(4, 3)),
                        C_e=rng.normal(size=(3, 4)), K_oo=Koo, D_oo=Doo,
                        B_o=rng.normal(size=(2, 3)), C_o=rng.normal(size=(3, 2)),
                        input_names=("u1", "u2", "u3"), output_names=("d", "s", "a"),
                        output_kinds=("disp", "strain", "accel"))


@pytest.mark.parametrize("h", [1e-3, 4e-3, 0.05])
def test_exact_discretisation_matches_cont2discrete(h):
    model = small_model()
    A, B, C, D = first_order(model)
    Ad, Bd, *_ = cont2discrete((A, B, C, D), h, method="zoh")
    rng = np.random.default_rng(1)
    x = rng.normal(size=model.n_states)
    u = rng.normal(size=3)
    # map our layout [q_e, v_e, q_o, v_o] <-> dense layout [q_e, q_o, v_e, v_o]
    n_m, n_r = model.n_modes, model.n_ritz
    perm = np.r_[0:n_m, n_m + n_r:2 * n_m + n_r, n_m:n_m + n_r, 2 * n_m + n_r:2 * (n_m + n_r)]
    ours = step(discretize(model, h), x[perm], u)
    ref = (Ad @ x + Bd @ u)[perm]
    np.testing.assert_allclose(ours, ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())
    np.testing.assert_allclose(output(model, x[perm], u), C @ x + D @ u, rtol=1e-12)


def test_modal_zoh_closed_form_equals_expm_branch():
    omega = np.array([5.0, 50.0, 500.0])
    c = 2 * 0.02 * omega
    h = 1e-3
    closed = np.array(modal_zoh(omega, c, h))
    # tiny omega*h forces the expm branch; compare against scaled problem
    from scipy.linalg import expm
    for i in range(3):
        A = np.array([[0, 1, 0], [-omega[i] ** 2, -c[i], 1], [0, 0, 0]])
        E = expm(A * h)
        ref = [E[0, 0], E[0, 1], E[1, 0], E[1, 1], E[0, 2], E[1, 2]]
        np.testing.assert_allclose(closed[:, i], ref, rtol=1e-10, atol=1e-15)


def test_step_force_response_matches_analytic():
    # undamped SDOF, unit-mass, step force F: q(t) = F/w^2 (1 - cos w t), exact at samples
    w, F, h = 2 * np.pi * 3.0, 2.5, 1e-3
    model = ReducedModel(omega=[w], modal_damping=[0.0], B_e=[[1.0]], C_e=[[1.0]],
                         K_oo=np.zeros((0, 0)), D_oo=np.zeros((0, 0)), B_o=np.zeros((0, 1)),
                         C_o=np.zeros((1, 0)), input_names=("f",), output_names=("q",),
                         output_kinds=("disp",))
    y, _ = simulate(model, h, np.full((2000, 1), F))
    t = np.arange(2000) * h
    np.testing.assert_allclose(y[:, 0], F / w**2 * (1 - np.cos(w * t)), atol=1e-13)


def test_frf_matches_dense_python_control():
    model = small_model(rigid=False)
    sys = to_statespace(model)
    f = np.geomspace(0.1, 100, 60)
    ours = frf(model, f)
    resp = control.frequency_response(sys, 2 * np.pi * f)
    ref = np.moveaxis(resp.complex, -1, 0)
    np.testing.assert_allclose(ours, ref, rtol=1e-9)


def test_reduced_frf_converges_to_full_fem(truss10_full):
    from structfmu.reduce import Damping, reduce
    f = np.array([2.0, 20.0])
    a, b = 0.1, 1e-5
    full = full_frf(truss10_full, f, ["strain_diag", "acc_tip_x"], ["fc_diag", "f_tip_x"],
                    a, b)
    outs, ins = ["strain_diag", "acc_tip_x"], ["fc_diag", "f_tip_x"]
    errs = []
    for n in (10, 40):
        # Ritz vectors for every input make the static part exact; modes do the rest
        red = frf(reduce(truss10_full, n, damping=Damping(alpha=a, beta=b),
                         ritz_inputs=["fc_long", "fc_diag", "f_tip_x", "f_tip_y"]),
                  f, outs, ins)
        errs.append(np.max(np.abs(red - full) / np.abs(full)))
    assert errs[1] < errs[0]
    assert errs[1] < 1e-3


# -- accelerometer bandwidth (structfmu.sensors) ------------------------------------------

def filtered(model, order=4, cutoff=150.0):
    from dataclasses import replace

    from structfmu.sensors import SensorLowpass

    return replace(model, accel_lowpass=SensorLowpass(order, cutoff))


@pytest.mark.parametrize("h", [1e-3, 4e-3])
def test_filtered_accel_discretisation_matches_cont2discrete(h):
    model = filtered(small_model())
    A, B, C, D = first_order(model)
    assert A.shape == (model.n_states,) * 2 and not np.any(D[2])
    Ad, Bd, *_ = cont2discrete((A, B, C, D), h, method="zoh")
    rng = np.random.default_rng(3)
    x = rng.normal(size=model.n_states)
    u = rng.normal(size=3)
    n_m, n_r, ns = model.n_modes, model.n_ritz, model.n_struct_states
    perm = np.r_[0:n_m, n_m + n_r:2 * n_m + n_r, n_m:n_m + n_r, 2 * n_m + n_r:ns,
                 ns:model.n_states]
    ours = step(discretize(model, h), x[perm], u)
    ref = (Ad @ x + Bd @ u)[perm]
    np.testing.assert_allclose(ours, ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())
    np.testing.assert_allclose(output(model, x[perm], u), C @ x + D @ u, rtol=1e-12)
    # the ZohStepper (used by the FMU) agrees with the pure step and has no feedthrough
    from structfmu.discrete import ZohStepper

    st = ZohStepper(model)
    st.x[:] = x[perm]
    st.step(u, h)
    np.testing.assert_allclose(st.x, ours, rtol=1e-12, atol=1e-15 * np.abs(ours).max())
    assert not st.has_feedthrough
    np.testing.assert_allclose(st.update_state_outputs(), output(model, ours, u), rtol=1e-12)


def test_filtered_frf_is_the_butterworth_times_the_acceleration():
    model = small_model()
    f = np.array([1.0, 22.0, 150.0, 600.0])
    H0, H1 = frf(model, f), frf(filtered(model), f)
    # |H| of an order-4 Butterworth: 1 / sqrt(1 + (f / fc)^8)
    gain = 1 / np.sqrt(1 + (f / 150.0) ** 8)
    np.testing.assert_allclose(np.abs(H1[:, 2]), np.abs(H0[:, 2]) * gain[:, None], rtol=1e-9)
    np.testing.assert_allclose(H1[:, :2], H0[:, :2], rtol=1e-12)
    A, B, C, D = first_order(filtered(model))
    s = 2j * np.pi * f[1]
    dense = C @ np.linalg.solve(s * np.eye(A.shape[0]) - A, B) + D
    np.testing.assert_allclose(dense, H1[1], rtol=1e-9)


def test_sampled_acceleration_aliases_stiff_local_modes_unless_filtered():
    """A 2.8 kHz Ritz mode rings after every held force step; sampled at 1 kHz the ringing
    swamps a small 22 Hz acceleration (as at a stiff strut), the 150 Hz low-pass removes it."""
    w_loc = 2 * np.pi * 2800.0
    model = ReducedModel(omega=[2 * np.pi * 30.0], modal_damping=[2 * 0.005 * 2 * np.pi * 30],
                         B_e=[[0.01]], C_e=[[0.01]], K_oo=[[w_loc**2]],
                         D_oo=[[2 * 0.02 * w_loc]], B_o=[[1.0]], C_o=[[1.0]],
                         input_names=("f",), output_names=("a",), output_kinds=("accel",))
    h, f0, n = 1e-3, 22.0, 4000
    t = np.arange(n) * h
    u = np.sin(2 * np.pi * f0 * t)[:, None]
    true = np.abs(frf(model, [f0])[0, 0, 0])

    def amplitude(m):
        y, _ = simulate(m, h, u)
        tail = t > 2.0  # transient gone (30 Hz mode, 0.5 %: tau = 1 s)
        basis = np.c_[np.sin(2 * np.pi * f0 * t), np.cos(2 * np.pi * f0 * t)][tail]
        return np.hypot(*np.linalg.lstsq(basis, y[tail, 0], rcond=None)[0])

    assert amplitude(model) > 3 * true  # aliased ringing, not the physics
    np.testing.assert_allclose(amplitude(filtered(model)),
                               true / np.sqrt(1 + (f0 / 150) ** 8), rtol=0.03)


def test_model_file_keeps_the_sensor_lowpass(tmp_path):
    model = filtered(small_model(), order=2, cutoff=80.0)
    back = ReducedModel.load(model.save(tmp_path / "m.npz"))
    assert back.accel_lowpass == model.accel_lowpass and back.n_states == model.n_states
    with pytest.raises(ValueError, match="order"):
        filtered(small_model(), order=0)


def test_stepper_takes_a_step_within_rounding_of_a_known_one_as_that_step():
    """(k+1)h - kh for 1 ms over 8 s gives 12 values up to 5.5e-13 apart: one
    discretisation (h's); a step 1e-6 apart is a new one; the cache keeps 8 steps."""
    from structfmu.discrete import ZohStepper

    st = ZohStepper(small_model())
    h = 1e-3
    assert st.discrete(h) is st.discrete((8000 * h) - (7999 * h))
    assert st.discrete(h * (1 + 5e-10)).h == h
    assert st.discrete(h * (1 + 1e-6)).h == h * (1 + 1e-6)
    for j in range(20):
        st.discrete(h * (2 + j))
    assert len(st._cache) == ZohStepper.CACHE
    assert st.discrete(h * 21).h == h * 21


@pytest.mark.parametrize("order", range(1, 11))
def test_sensor_lowpass_is_scipys_butterworth_bit_for_bit(order):
    """The filter's state space is what scipy.signal's analog Butterworth (zpk) and
    zpk2ss give, bit for bit, at corners from 1 Hz to 20 kHz: the project computes it
    without importing scipy.signal."""
    from scipy import signal

    from structfmu.sensors import SensorLowpass

    for hz in (1.0, 22.0, 150.0, 333.3, 2e4):
        z, p, k = signal.butter(order, 2 * np.pi * hz, analog=True, output="zpk")
        want = signal.zpk2ss(z, p, k)
        got = SensorLowpass(order, hz).siso()
        for a, b in zip(got, want[:3]):
            np.testing.assert_array_equal(a, b)
        assert not np.any(want[3])
