"""Named designs: SMD emulation, isolation band-pass and poles/zeros, gain optimiser."""

import math

import control
import numpy as np
import pytest
from scipy import signal

from ctrlfmu import designs
from ctrlfmu.analysis import closed_loop, frequency_response, mode_damping, optimise_gain
from ctrlfmu.designs import DESIGNS, design, write_designs
from ctrlfmu.law import load_law


def inverse_tustin(z, dt):
    """s of the bilinear map z = (1 + s dt/2) / (1 - s dt/2) (exact inverse)."""
    return 2 / dt * (z - 1) / (z + 1)


def cont(sys, f_hz):
    """Continuous frequency response of a SISO system at ``f_hz`` (Hz)."""
    return np.asarray(sys(2j * np.pi * np.atleast_1d(np.asarray(f_hz, dtype=float))),
                      dtype=complex).reshape(-1)


@pytest.mark.parametrize("name,mode_hz", [("truss10_strain_diag", 8.4),
                                          ("truss10_strain_long", 9.5)])
def test_truss_design_emulates_spring_mass_damper(name, mode_hz):
    law = design(name)
    assert law.dt == 1 / 250 and law.delayed and (law.n_inputs, law.n_outputs) == (1, 1)
    gain = designs.DIAG_PLANT_GAIN if "diag" in name else designs.LONG_PLANT_GAIN
    par = designs.TRUSS10_DIAG if "diag" in name else designs.TRUSS10_LONG
    kc = designs.virtual_absorber_tf(mode_hz, gain, **par)
    f_c = par["tuning"] * mode_hz  # absorber frequency = prewarp frequency
    # Static gain: Tustin maps s = 0 to z = 1, so K(1) = loop_gain / plant_gain exactly.
    np.testing.assert_allclose(frequency_response(law, [0.0])[0, 0, 0],
                               par["loop_gain"] / gain, rtol=1e-10)
    # Prewarped at the absorber: the response there is the continuous one.
    np.testing.assert_allclose(frequency_response(law, [f_c], include_delay=False)[0, 0],
                               cont(kc, f_c), rtol=1e-9)
    # Tustin identity: H_d(f) = H_c(f') with f' = f_c tan(pi f dt) / tan(pi f_c dt).
    f = np.linspace(0.2, 120.0, 300)
    warped = f_c * np.tan(np.pi * f * law.dt) / np.tan(np.pi * f_c * law.dt)
    np.testing.assert_allclose(frequency_response(law, f, include_delay=False)[0, 0],
                               cont(kc, warped), rtol=1e-9)
    # Below Nyquist/4 (31.25 Hz) the frequency warp is at most w - 1 with
    # w = f_c tan(pi 31.25 dt) / (31.25 tan(pi f_c dt)) (5.4 % for f_c = 5 Hz); above the
    # absorber |K| ~ f^-2, so the magnitude error is at most w^2 - 1 (11.1 %); the phase
    # error is at most the resonator's phase change over [f, w f], whose slope
    # |d phase / d ln f| peaks at 1 / zeta (at the absorber frequency): ln(w) / zeta.
    f = np.linspace(0.1, 31.25, 400)
    w = f_c * np.tan(np.pi * 31.25 * law.dt) / (31.25 * np.tan(np.pi * f_c * law.dt))
    ratio = frequency_response(law, f, include_delay=False)[0, 0] / cont(kc, f)
    assert np.max(np.abs(np.abs(ratio) - 1)) < w**2 - 1 + 1e-3
    assert np.max(np.abs(np.angle(ratio))) < np.log(w) / par["zeta"]
    # It is a second-order resonator at the absorber frequency with the design damping
    # (inverse Tustin with prewarp scale).
    scale = 2 * np.pi * f_c / (2 / law.dt * np.tan(np.pi * f_c * law.dt))
    s = inverse_tustin(np.linalg.eigvals(law.A), law.dt) * scale
    np.testing.assert_allclose(np.abs(s), 2 * np.pi * f_c, rtol=1e-9)
    np.testing.assert_allclose(-s.real / np.abs(s), par["zeta"], rtol=1e-9)


def test_testbed_isolation_poles_and_zeros():
    law = design("testbed_isolation")
    assert law.dt == 1e-3 and (law.n_inputs, law.n_outputs) == (2, 1)
    assert law.inputs == ("payload_accel", "bus_accel")
    s = np.sort_complex(inverse_tustin(np.linalg.eigvals(law.A), law.dt))
    # Two compensator poles at -1 rad/s.  A double root is ill-conditioned: rounding of
    # order eps in A splits it in z by up to about sqrt(eps), i.e. by 2/dt sqrt(eps) =
    # 3e-5 rad/s in s (measured 0.8-1.4e-6 with three BLAS kernels), so each root is
    # checked to that bound; their mean (the trace of the pair) is well conditioned and
    # is checked tightly.
    slow = s[np.abs(s) < 10]
    assert slow.size == 2
    np.testing.assert_allclose(slow.mean(), -1.0, rtol=0, atol=1e-9)
    split = 2 / law.dt * math.sqrt(np.finfo(float).eps)
    np.testing.assert_allclose(slow, [-1.0, -1.0], rtol=0, atol=split)
    # The band-pass poles are the analog Butterworth ones with prewarped edges.
    w = 2 / law.dt * np.tan(np.pi * np.array([20.0, 60.0]) * law.dt)
    bp_poles = signal.butter(2, w, btype="bandpass", analog=True, output="zpk")[1]
    np.testing.assert_allclose(np.sort_complex(s[np.abs(s) >= 10]), np.sort_complex(bp_poles),
                               rtol=1e-8)
    # Zeros of each input channel: double zero at -100 rad/s, the band-pass double zero
    # at s = 0 (z = 1) and two at z = -1 (the band-pass's excess poles, s = infinity).
    for j in range(2):
        sys = control.ss(law.A, law.B[:, [j]], law.C, law.D[:, [j]], law.dt)
        z = sys.zeros()
        finite = z[np.abs(z + 1) > 1e-3]
        s_z = np.sort_complex(inverse_tustin(finite, law.dt))
        # A double root moves by ~sqrt(rounding error): compare the pair's mean tightly
        # and each root to 1e-4 relative.
        pair = s_z[np.abs(s_z) > 10]   # the split s = 0 pair can reach about 1.3 rad/s
        np.testing.assert_allclose(pair.mean(), -100.0, rtol=1e-8)
        np.testing.assert_allclose(pair, [-100.0, -100.0], rtol=1e-4)
        assert np.sum(np.abs(z + 1) <= 1e-3) == 2
        # The double zero at s = 0 (z = 1): its roots are too ill-conditioned to compare,
        # so check the response instead: zero at DC and +40 dB/decade far below 1 rad/s.
        h = frequency_response(law, [0.0, 1e-4, 2e-4], include_delay=False)[0, j]
        assert abs(h[0]) < 1e-9     # V/(m/s^2); the band-centre gain is 26 V/(m/s^2)
        np.testing.assert_allclose(abs(h[2] / h[1]), 4.0, rtol=1e-3)


def test_testbed_isolation_band_pass_20_60_hz():
    law = design("testbed_isolation")
    dt = law.dt
    comp = designs.isolation_compensator_tf()
    f = np.array([20.0, 34.641016151377546, 60.0, 5.0, 200.0])
    h = frequency_response(law, f, include_delay=False)[0, 0]
    # Divide out the compensator (exact under Tustin: evaluate it at the warped
    # frequency) and compare with scipy's digital Butterworth band-pass at 1000 Hz,
    # which is -3 dB exactly at 20 and 60 Hz.
    warped = np.tan(np.pi * f * dt) / (np.pi * dt)
    band = h / cont(comp, warped)
    b, a = signal.butter(2, [20.0, 60.0], btype="bandpass", fs=1 / dt)
    ref = signal.freqz(b, a, worN=f, fs=1 / dt)[1]
    np.testing.assert_allclose(band / band[1], ref / ref[1], rtol=1e-9)
    np.testing.assert_allclose(np.abs(ref[[0, 2]]), 1 / math.sqrt(2), rtol=1e-9)
    # The full law (compensator x band-pass): its -3 dB points below the peak match the
    # continuous cascade within 2 % (Tustin warp at 60 Hz and 1000 Hz is 1.2 %), and the
    # compensator's tilt (|C| = 1.6 at 20 Hz, 1.07 at 60 Hz) shifts them by < 15 % from
    # the filter's 20 and 60 Hz edges.
    fg = np.linspace(5.0, 200.0, 39001)
    mag = np.abs(frequency_response(law, fg)[0, 0])
    wp = 2 / dt * np.tan(np.pi * np.array([20.0, 60.0]) * dt)
    zc, pc, kc = signal.butter(2, 2 * np.pi * np.array([20.0, 60.0]), btype="bandpass",
                               analog=True, output="zpk")
    h_c = np.abs(cont(comp * control.zpk(zc, pc, kc), fg))

    def edges(m):
        inside = fg[m >= m.max() / math.sqrt(2)]
        return np.array([inside.min(), inside.max()])

    np.testing.assert_allclose(edges(mag), edges(h_c), rtol=0.02)
    np.testing.assert_allclose(edges(mag), [20.0, 60.0], rtol=0.15)
    assert wp[0] > 2 * np.pi * 20.0     # prewarping moved the analog edges outward
    # Unit magnitude at the band centre, so the gains are in V per m/s^2 there.
    # Default gains: the testbed design's (payload, bus) gains in V per m/s^2.
    from ctrlfmu.designs import TESTBED_ISOLATION_GAINS
    np.testing.assert_allclose(np.abs(frequency_response(law, [34.641016151377546])[0, :, 0]),
                               np.abs(TESTBED_ISOLATION_GAINS), rtol=1e-9)


def test_testbed_gains_are_separate_per_input():
    law = designs.testbed_isolation(payload_gain=-10.0, bus_gain=4.0)
    h = frequency_response(law, [34.641016151377546])[0, :, 0]
    np.testing.assert_allclose(np.abs(h), [10.0, 4.0], rtol=1e-6)
    np.testing.assert_allclose(h[1] / h[0], -0.4, rtol=1e-12)


def test_eos_isolation_is_strain_plus_rate_through_low_pass():
    law = designs.eos_isolation(strain_gain=1000.0, rate_gain=10.0, lowpass_hz=100.0)
    assert law.dt == 1e-3 and law.n_states == 2
    # static gain = strain_gain (Tustin keeps DC)
    np.testing.assert_allclose(frequency_response(law, [0.0])[0, 0, 0], 1000.0, rtol=1e-10)
    # Exact against the continuous design at the warped frequency.
    wc = 2 / law.dt * np.tan(np.pi * 100.0 * law.dt)
    zl, pl, kl = signal.butter(2, wc, analog=True, output="zpk")
    hc = control.zpk(zl, pl, kl) * control.tf([10.0, 1000.0], [1.0])
    f = np.array([1.0, 15.9, 50.0, 100.0, 300.0])
    warped = np.tan(np.pi * f * law.dt) / (np.pi * law.dt)
    np.testing.assert_allclose(frequency_response(law, f, include_delay=False)[0, 0],
                               cont(hc, warped), rtol=1e-9)
    # The low-pass corner (prewarped) sits at 100 Hz: -3 dB relative to the PD term.
    pd = 1000.0 + 10.0 * 1j * wc      # the PD term at the warped corner frequency
    np.testing.assert_allclose(np.abs(frequency_response(law, [100.0])[0, 0, 0]) / abs(pd),
                               1 / math.sqrt(2), rtol=1e-9)


def truss_like_plant(mode_hz=8.4, gain=designs.DIAG_PLANT_GAIN):
    """Collocated voltage-to-strain plant: static residual + two lightly damped modes."""
    w1, w2 = 2 * np.pi * mode_hz, 2 * np.pi * 9.5
    return gain * (control.tf([0.3], [1]) + control.tf([0.5 * w1**2], [1, 2 * 0.0018 * w1, w1**2])
                   + control.tf([0.2 * w2**2], [1, 2 * 0.004 * w2, w2**2]))


def test_optimise_gain_maximises_damping_of_target_mode():
    plant = truss_like_plant()
    law = design("truss10_strain_diag")
    res = optimise_gain(plant, law, 8.4)
    np.testing.assert_allclose(res.open_loop_damping, 0.0018, rtol=1e-6)   # ZOH keeps poles
    assert res.damping > 10 * res.open_loop_damping
    assert np.all(np.abs(closed_loop(plant, res.law).poles()) < 1)
    # A local maximum: neighbouring gains damp less.
    for factor in (0.8, 1.25):
        poles = closed_loop(plant, law.with_gain(res.gain * factor)).poles()
        f_n, zeta = mode_damping(poles, law.dt)
        assert np.min(zeta[(f_n > 4.2) & (f_n < 16.8)]) < res.damping
    # The named design tuned on the plant is the same law.
    tuned = designs.truss10_strain_diag(plant)
    # (dcgain of the summed plant differs from DIAG_PLANT_GAIN by rounding only)
    np.testing.assert_allclose(tuned.C, res.law.C, rtol=1e-6)


def test_optimise_gain_accepts_a_discrete_plant():
    law = design("truss10_strain_diag")
    plant_d = control.sample_system(control.ss(truss_like_plant()), law.dt, method="zoh")
    res_c = optimise_gain(truss_like_plant(), law, 8.4)
    res_d = optimise_gain(plant_d, law, 8.4)
    np.testing.assert_allclose(res_d.gain, res_c.gain, rtol=1e-6)
    with pytest.raises(ValueError, match="differs from the law"):
        optimise_gain(control.sample_system(control.ss(truss_like_plant()), 0.001), law, 8.4)


def test_design_registry_and_resource_files(tmp_path):
    assert set(DESIGNS) == {"truss10_strain_diag", "truss10_strain_long", "testbed_isolation",
                            "eos_isolation"}
    paths = write_designs(tmp_path)
    assert sorted(p.stem for p in paths) == sorted(DESIGNS)
    for p in paths:
        assert load_law(p).name == p.stem
    with pytest.raises(KeyError, match="unknown controller design 'nope'"):
        design("nope")
