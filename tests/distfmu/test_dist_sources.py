"""Disturbance sources: spectra, scaling laws, integrals, replay, random PSD."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import cumulative_trapezoid
from scipy.signal import welch

from distfmu.sources import (
    BandLimitedRandom,
    Chopper,
    Gated,
    Harmonic,
    ScanMirror,
    Slew,
    SourceError,
    SpeedProfile,
    Stepper,
    Sum,
    Table,
    WheelImbalance,
    advance_wheel,
)


def amplitude_spectrum(x, fs, window=True):
    """Single-sided sine-amplitude spectrum, Hann window with coherent gain removed.

    For a sinusoid of amplitude ``a`` on an FFT bin the peak is exactly ``a``.  The Hann
    window spreads each line over three bins; ``window=False`` (rectangular) keeps a line
    in one bin, exact when the record holds a whole number of periods.
    """
    w = np.hanning(x.size + 1)[:-1] if window else np.ones(x.size)  # periodic Hann
    spec = np.abs(np.fft.rfft((x - x.mean()) * w)) * 2 / w.sum()
    return np.fft.rfftfreq(x.size, 1 / fs), spec


def peak_at(f, spec, f0):
    return spec[int(np.argmin(np.abs(f - f0)))]


# --------------------------------------------------------------------------- harmonic


def test_harmonic_spectrum_peaks_at_harmonics_with_amplitudes():
    src = Harmonic(frequency=22.0, amplitudes=(0.5, 0.15, 0.05), phases=(0.3, 1.0, -2.0),
                   direction=(0.0, 3.0, 4.0), kind="force")
    fs, dur = 1000.0, 20.0  # 22 Hz and its harmonics fall on 0.05 Hz bins
    t = np.arange(0, dur, 1 / fs)
    w = src.wrench(t)
    # the force lies along the unit direction (0, 0.6, 0.8); no torque
    np.testing.assert_allclose(w[:, [0, 3, 4, 5]], 0.0)
    np.testing.assert_allclose(w[:, 1] * 0.8, w[:, 2] * 0.6, atol=1e-12)
    f, spec = amplitude_spectrum(w[:, 2] / 0.8, fs)
    for k, a in zip((1, 2, 3), (0.5, 0.15, 0.05)):
        np.testing.assert_allclose(peak_at(f, spec, 22.0 * k), a, rtol=1e-6)
    # the three largest lines are exactly those harmonics
    f, spec = amplitude_spectrum(w[:, 2] / 0.8, fs, window=False)
    top = np.sort(f[np.argsort(spec)[-3:]])
    np.testing.assert_allclose(top, [22.0, 44.0, 66.0])


def test_harmonic_rejects_mismatched_lengths():
    with pytest.raises(SourceError, match="phases has 1 entries; expected 2"):
        Harmonic(frequency=1.0, amplitudes=(1.0, 2.0), phases=(0.0,))


# --------------------------------------------------------------------------- chopper


@pytest.mark.parametrize("rise", [0.0, 0.01])
def test_chopper_fourier_series(rise):
    # square wave of amplitude a with linear edges of duration tau:
    # b_k = 4 a / (pi k) * sinc(k f tau) for odd k, 0 for even k
    a, f0 = 0.02, 7.0
    src = Chopper(frequency=f0, amplitude=a, rise_time=rise)
    fs = f0 * 2000  # 2000 samples per period
    t = np.arange(0, 10 / f0, 1 / fs)
    x = src.wrench(t)[:, 3]
    f, spec = amplitude_spectrum(x, fs)
    for k in (1, 3, 5, 7):
        expected = 4 * a / (math.pi * k) * abs(np.sinc(k * f0 * rise))
        np.testing.assert_allclose(peak_at(f, spec, k * f0), expected, rtol=2e-3)
    for k in (2, 4):
        assert peak_at(f, spec, k * f0) < 1e-3 * a


def test_chopper_rise_time_must_fit_in_half_period():
    with pytest.raises(SourceError, match="rise_time"):
        Chopper(frequency=10.0, amplitude=1.0, rise_time=0.06)


# --------------------------------------------------------------------------- scan mirror


def test_scan_mirror_sweeps_its_amplitude_with_zero_net_momentum():
    src = ScanMirror(inertia=0.6, period=6.6, amplitude=1.2, retrace_fraction=0.3,
                     turnaround=0.2, axis=(1.0, 0.0, 0.0))
    fs = 20000.0  # edges fall between samples: rate error <= alpha / fs ~ 0.1 %
    t = np.arange(0, 3 * src.period, 1 / fs)
    torque = src.wrench(t)[:, 3]
    alpha = -torque / src.inertia
    # mirror rate and angle by integration, starting mid-sweep at -amplitude-ish
    # t = 0 is the middle of the retrace -> sweep reversal: the rate is half-way
    rate = 0.5 * (src.scan_rate + src.retrace_rate) + cumulative_trapezoid(alpha, t,
                                                                          initial=0.0)
    angle = cumulative_trapezoid(rate, t, initial=0.0)
    # net angular impulse per period is zero
    one = t < src.period
    assert abs(np.sum(torque[one]) / fs) < 1e-3 * src.inertia * src.scan_rate
    # rate alternates between scan and retrace rates; angle sweeps 2 * amplitude
    np.testing.assert_allclose(rate.max(), src.scan_rate, rtol=1e-3)
    np.testing.assert_allclose(rate.min(), src.retrace_rate, rtol=1e-3)
    # outside the turnarounds the angle is the ideal triangle wave (-A at t = 0, 0 at
    # mid-sweep); at the reversal centre (t = 0) the ramp has rounded it by dw tau / 8
    dw_tau = (src.scan_rate - src.retrace_rate) * src.turnaround
    t_mid = 0.5 * (1 - src.retrace_fraction) * src.period
    i_mid = int(round(t_mid * fs))
    np.testing.assert_allclose(angle[i_mid] - angle[0], src.amplitude - dw_tau / 8,
                               rtol=1e-3)
    assert 2 * src.amplitude - dw_tau / 4 < np.ptp(angle) < 2 * src.amplitude
    # peak torque is J * (rate jump) / turnaround
    jump = src.inertia * (src.scan_rate - src.retrace_rate) / src.turnaround
    np.testing.assert_allclose(np.abs(torque).max(), jump)


def test_scan_mirror_spectrum_is_periodic_at_scan_rate():
    src = ScanMirror(inertia=0.02, period=12.0, amplitude=0.455, turnaround=0.1)
    fs = 100.0
    t = np.arange(0, 20 * src.period, 1 / fs)
    f, spec = amplitude_spectrum(src.wrench(t)[:, 3], fs, window=False)
    lines = f[spec > 0.05 * spec.max()]
    # every significant line is a multiple of 1 / period
    np.testing.assert_allclose(lines * src.period, np.round(lines * src.period), atol=1e-9)


# --------------------------------------------------------------------------- slew


@pytest.mark.parametrize("angle,max_rate,max_accel", [
    (math.radians(24.0), 0.05, 1.0),     # trapezoidal (VNIR-like)
    (-math.radians(8.55), 0.5, 0.7),     # triangular: rate limit not reached
])
def test_slew_integrates_to_commanded_angle(angle, max_rate, max_accel):
    inertia = 4.0
    src = Slew(angle=angle, max_rate=max_rate, max_accel=max_accel, inertia=inertia,
               start=1.0, axis=(0.0, 1.0, 0.0))
    fs = 10000.0
    t = np.arange(0, src.start + src.duration + 1.0, 1 / fs)
    torque = src.wrench(t)[:, 4]
    alpha = -torque / inertia  # instrument acceleration from the reaction torque
    rate = cumulative_trapezoid(alpha, t, initial=0.0)
    theta = cumulative_trapezoid(rate, t, initial=0.0)
    np.testing.assert_allclose(theta[-1], angle, rtol=1e-3)
    assert abs(rate[-1]) < 1e-3 * max_rate
    assert np.abs(rate).max() <= max_rate * (1 + 1e-3)
    assert np.abs(torque).max() == pytest.approx(inertia * max_accel)
    # analytic rate agrees with the integrated one
    np.testing.assert_allclose(src.rate(t), rate, atol=2 * max_accel / fs)


def test_repeating_alternating_slew_returns_home():
    src = Slew(angle=0.3, max_rate=0.1, max_accel=0.5, inertia=1.0, repeat=10.0)
    fs = 2000.0
    t = np.arange(0, 20.0, 1 / fs) + 0.5 / fs
    rate = src.rate(t)
    theta = np.cumsum(rate) / fs
    np.testing.assert_allclose(theta[int(9.9 * fs)], 0.3, rtol=1e-3)
    assert abs(theta[-1]) < 1e-3


def test_slew_repeat_shorter_than_duration_is_an_error():
    with pytest.raises(SourceError, match="repeat must be at least"):
        Slew(angle=1.0, max_rate=0.1, max_accel=1.0, inertia=1.0, repeat=5.0)


# --------------------------------------------------------------------------- stepper


def test_stepper_impulse_and_lines():
    src = Stepper(step_rate=2.0, peak_torque=0.5, pulse_width=0.05, bipolar=False)
    fs = 4000.0
    t = np.arange(0, 10.0, 1 / fs)
    m = src.wrench(t)[:, 4]
    np.testing.assert_allclose(np.sum(m[t < 0.5]) / fs, src.impulse, rtol=1e-4)
    f, spec = amplitude_spectrum(m, fs, window=False)
    lines = f[spec > 0.05 * spec.max()]
    np.testing.assert_allclose(lines / 2.0, np.round(lines / 2.0), atol=1e-9)
    # bipolar pulses have no mean torque
    bip = Stepper(step_rate=2.0, peak_torque=0.5, pulse_width=0.05)
    assert abs(np.mean(bip.wrench(t)[:, 4])) < 1e-9


# --------------------------------------------------------------------------- wheel


def _wheel(speed):
    return WheelImbalance(harmonics=(1.0, 2.0, 2.9), force_coeffs=(2e-7, 2e-8, 1e-8),
                          torque_coeffs=(2e-6, 2e-7, 1e-7), speed=speed,
                          axis=(0.0, 0.0, 1.0))


def test_wheel_force_scales_with_speed_squared():
    fs, dur = 2000.0, 10.0
    t = np.arange(0, dur, 1 / fs)
    freqs = np.array([5.0, 10.0, 20.0, 40.0, 80.0])  # on 0.1 Hz bins
    amps = []
    for f0 in freqs:
        w = _wheel(2 * np.pi * f0).wrench(t)
        f, spec = amplitude_spectrum(w[:, 0], fs)
        amps.append(peak_at(f, spec, f0))
        # harmonics at h * f0 with amplitude C_h * Omega^2 (integer h on-bin)
        np.testing.assert_allclose(peak_at(f, spec, 2 * f0), 2e-8 * (2 * np.pi * f0) ** 2,
                                   rtol=1e-3)
    slope, _ = np.polyfit(np.log(2 * np.pi * freqs), np.log(amps), 1)
    np.testing.assert_allclose(slope, 2.0, atol=1e-3)
    np.testing.assert_allclose(amps, 2e-7 * (2 * np.pi * freqs) ** 2, rtol=1e-3)


def test_wheel_radial_force_rotates_in_wheel_plane():
    src = WheelImbalance(harmonics=(1.0,), force_coeffs=(1e-6,), torque_coeffs=(1e-5,),
                         speed=100.0, axis=(0.0, 0.0, 1.0))
    w = src.wrench(np.linspace(0, 1, 1001))
    np.testing.assert_allclose(np.hypot(w[:, 0], w[:, 1]), 1e-6 * 100.0**2)
    np.testing.assert_allclose(np.hypot(w[:, 3], w[:, 4]), 1e-5 * 100.0**2)
    np.testing.assert_allclose(w[:, [2, 5]], 0.0, atol=1e-15)


def test_wheel_speed_profile_phase_is_exact_integral():
    prof = SpeedProfile(times=(1.0, 3.0, 4.0), speeds=(10.0, 30.0, 30.0))
    # hold 10 rad/s before t = 1, ramp to 30 by t = 3, hold after
    np.testing.assert_allclose(prof.phase([0.0, 1.0, 2.0, 3.0, 5.0]),
                               [0.0, 10.0, 25.0, 50.0, 110.0])
    src = _wheel(prof)
    t = np.linspace(0, 5, 51)
    np.testing.assert_allclose(src.wrench(t), src.wrench_at(prof.phase(t), prof.speed(t)))


def test_wheel_stepping_form_matches_closed_form_for_constant_speed():
    src = _wheel(150.0)
    theta, h = 0.0, 0.01
    for _ in range(100):
        theta = advance_wheel(theta, 150.0, h)
    np.testing.assert_allclose(src.wrench_at(theta, 150.0), src.wrench(1.0), atol=1e-12)


# --------------------------------------------------------------------------- table


def test_table_exact_at_samples_and_linear_between():
    times = np.array([0.0, 0.5, 2.0, 3.0])
    values = np.arange(24.0).reshape(4, 6) ** 1.5
    tab = Table(times, values)
    np.testing.assert_allclose(tab.wrench(times), values)
    mid = 0.25 * times[1:] + 0.75 * times[:-1]
    np.testing.assert_allclose(tab.wrench(mid), 0.25 * values[1:] + 0.75 * values[:-1])
    np.testing.assert_allclose(tab.wrench([-1.0, 4.0]), 0.0)
    hold = Table(times, values, fill="hold")
    np.testing.assert_allclose(hold.wrench([-1.0, 4.0]), values[[0, -1]])


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(0.01, 10.0), min_size=2, max_size=20),
       st.integers(0, 2**32 - 1), st.floats(0.0, 1.0))
def test_table_interpolation_property(steps, seed, frac):
    times = np.cumsum(steps)
    values = np.random.default_rng(seed).normal(size=(times.size, 6))
    tab = Table(times, values)
    i = len(times) // 2 - 1
    t = times[i] + frac * (times[i + 1] - times[i])
    np.testing.assert_allclose(tab.wrench(t), (1 - frac) * values[i] + frac * values[i + 1],
                               rtol=1e-9, atol=1e-9)


def test_table_csv_named_columns(tmp_path):
    path = tmp_path / "meas.csv"
    path.write_text("t,a,b,c,d,e,f,comment\n0,1,2,3,4,5,6,0\n1,2,4,6,8,10,12,0\n")
    tab = Table.from_csv(path, columns=list("abcdef"), time_column="t")
    np.testing.assert_allclose(tab.wrench(0.5), [1.5, 3, 4.5, 6, 7.5, 9])
    path2 = tmp_path / "std.csv"
    path2.write_text("time,Fx,Fy,Fz,Mx,My,Mz\n0,1,1,1,1,1,1\n2,3,3,3,3,3,3\n")
    np.testing.assert_allclose(Table.from_csv(path2).wrench(1.0), np.full(6, 2.0))


def test_table_errors(tmp_path):
    with pytest.raises(SourceError, match=r"strictly increasing, but sample 2 \(t = 0.5 s\)"):
        Table(np.array([0.0, 1.0, 0.5]), np.zeros((3, 6)))
    with pytest.raises(SourceError, match=r"values have shape \(3, 5\); expected \(3, 6\)"):
        Table(np.array([0.0, 1.0, 2.0]), np.zeros((3, 5)))
    path = tmp_path / "bad.csv"
    path.write_text("time,Fx,Fy,Fz,Mx,My\n0,1,2,3,4,5\n1,1,2,3,4,5\n")
    with pytest.raises(SourceError, match=r"missing column\(s\) \['Mz'\]"):
        Table.from_csv(path)
    assert issubclass(SourceError, ValueError)


# --------------------------------------------------------------------------- random


def test_band_limited_random_matches_requested_psd():
    # one-sided PSD: 1e-4 N^2/Hz flat from 5 to 40 Hz, sloping to zero at 2 and 60 Hz
    src = BandLimitedRandom(psd_freqs=(2.0, 5.0, 40.0, 60.0),
                            psd_values=(0.0, 1e-4, 1e-4, 0.0), seed=7,
                            sample_rate=500.0, n_samples=2**18)
    t = np.arange(src.n_samples) / src.sample_rate  # the grid: no interpolation loss
    x = src.signal(t)
    # variance equals the integral of the PSD on the grid (deterministic amplitudes)
    df = src.sample_rate / src.n_samples
    grid = np.arange(src.n_samples // 2 + 1) * df
    np.testing.assert_allclose(np.var(x), np.sum(src.psd(grid)[1:-1]) * df, rtol=1e-9)
    f, pxx = welch(x, fs=src.sample_rate, nperseg=1024)
    band = (f > 8) & (f < 37)
    ratio = pxx[band] / src.psd(f[band])
    # Welch with 1024-point Hann segments, 50 % overlap: K = 511 segments, so each bin
    # has a relative standard deviation of about 1/sqrt(0.9 K) ~ 4.7 %; the band mean
    # over ~59 bins is then within 1 %, and every bin within 5 sigma ~ 25 %.
    np.testing.assert_allclose(np.mean(ratio), 1.0, atol=0.02)
    assert np.all(np.abs(ratio - 1.0) < 0.25)
    # out of band: below 1e-3 of the level (leakage of the Hann window)
    assert np.all(pxx[(f > 80) & (f < 240)] < 1e-3 * 1e-4)


def test_band_limited_random_is_a_pure_function_of_seed_and_time():
    kw = dict(psd_freqs=(1.0, 10.0), psd_values=(1.0, 1.0), sample_rate=200.0, n_samples=4096)
    a, b, c = BandLimitedRandom(seed=1, **kw), BandLimitedRandom(seed=1, **kw), \
        BandLimitedRandom(seed=2, **kw)
    t = np.array([0.013, 5.0, 7.77])
    np.testing.assert_array_equal(a.wrench(t), b.wrench(t))
    np.testing.assert_array_equal(a.wrench(t[::-1])[::-1], a.wrench(t))  # order-free
    assert np.max(np.abs(a.wrench(t) - c.wrench(t))) > 1e-3
    # periodic with the record length, linear between grid points
    np.testing.assert_allclose(a.signal(t + a.period), a.signal(t), atol=1e-9)
    g = np.arange(3) / a.sample_rate
    np.testing.assert_allclose(a.signal(g[0] + 0.3 / a.sample_rate),
                               0.7 * a.signal(g[0]) + 0.3 * a.signal(g[1]))


# --------------------------------------------------------------------------- combinators


def test_sum_and_gate():
    h = Harmonic(frequency=1.0, amplitudes=(1.0,), direction=(1.0, 0.0, 0.0))
    c = Chopper(frequency=2.0, amplitude=0.5, direction=(0.0, 0.0, 1.0))
    t = np.linspace(0.1, 3.0, 30)
    np.testing.assert_allclose(Sum((h, c)).wrench(t), h.wrench(t) + c.wrench(t))
    g = Gated(h, scale=2.0, start=1.0, stop=2.0)
    w = g.wrench(t)
    inside = (t >= 1.0) & (t < 2.0)
    np.testing.assert_allclose(w[inside], 2.0 * h.wrench(t[inside]))
    np.testing.assert_allclose(w[~inside], 0.0)
