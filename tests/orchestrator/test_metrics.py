"""Tests of the jitter metrics against brute force and analytic references."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.lib.stride_tricks import sliding_window_view
from scipy.signal import cont2discrete, freqz, lfilter

import orchestrator.metrics as M

# ---------------------------------------------------------------- peak-to-peak


def brute_peak_to_peak_series(x, n):
    """Reference: range of every window of n consecutive samples (stride tricks)."""
    v = sliding_window_view(x, n, axis=-1)
    return v.max(axis=-1) - v.min(axis=-1)


@settings(max_examples=200, deadline=None)
@given(
    n_samples=st.integers(2, 300),
    frac=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**32 - 1),
    rows=st.integers(1, 3),
)
def test_peak_to_peak_matches_brute_force(n_samples, frac, seed, rows):
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.normal(size=(rows, n_samples)), axis=-1)
    m = 1 + int(frac * (n_samples - 2))  # sample intervals in the window, 1..n_samples-1
    dt = 0.01
    ref = brute_peak_to_peak_series(x, m + 1)
    got = M.peak_to_peak_series(x, dt, m * dt)
    assert got.shape == ref.shape == (rows, n_samples - m)
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_array_equal(M.peak_to_peak(x, dt, m * dt), ref.max(axis=-1))


def test_peak_to_peak_time_axis_argument():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(50, 4))
    np.testing.assert_array_equal(
        M.peak_to_peak(x, 1.0, 7.0, axis=0), M.peak_to_peak(x.T, 1.0, 7.0)
    )


def test_window_maps_to_closed_interval_of_samples():
    # T = 10 ms at dt = 1 ms: the closed interval [t, t + T] holds 11 samples.
    assert M.window_samples(0.010, 0.001) == 11
    # A step inside the record: any window of >= 1 interval that straddles it sees it.
    x = np.r_[np.zeros(5), np.ones(5)]
    assert M.peak_to_peak(x, 0.001, 0.001) == 1.0


# Sine of amplitude A and period P.  A window of length T centred on a zero crossing sees
# A sin(w T/2) - A sin(-w T/2) = 2 A sin(pi T / P).  No window does better when T <= P/2:
# on a monotonic stretch the range 2A |cos(w c)| sin(pi T/P) (c = window centre) is largest
# at a zero crossing; a window holding a crest has range at most A (1 - cos(2 pi T/P))
# = 2 A sin^2(pi T/P) <= 2 A sin(pi T/P).  For T >= P/2 a window holds a crest and a trough,
# giving 2A.
def sine_peak_to_peak(amplitude, period, window):
    if window >= period / 2:
        return 2.0 * amplitude
    return 2.0 * amplitude * math.sin(math.pi * window / period)


@pytest.mark.parametrize("window_samples", [2, 10, 50, 100, 198, 200, 300, 400, 1000])
def test_sine_peak_to_peak_exact_on_grid(window_samples):
    # P/(2 dt) and T/(2 dt) are whole numbers: the optimal window's ends fall on samples.
    amplitude, period, dt = 2.5, 0.8, 0.002  # P = 400 samples
    t = np.arange(4000) * dt
    x = amplitude * np.sin(2 * np.pi * t / period)
    window = window_samples * dt
    np.testing.assert_allclose(
        M.peak_to_peak(x, dt, window), sine_peak_to_peak(amplitude, period, window),
        rtol=1e-12,
    )


@settings(max_examples=60, deadline=None)
@given(phase=st.floats(0, 2 * math.pi), frac=st.floats(0.01, 1.5))
def test_sine_peak_to_peak_any_phase_within_sampling_bound(phase, frac):
    # Off grid, the best sampled window is at most dt/2 from the optimum; the range falls
    # by at most a factor cos(pi dt / P) >= 1 - (pi dt / P)^2 / 2 (and never exceeds it).
    amplitude, period, dt = 1.3, 1.0, 0.01
    t = np.arange(600) * dt
    x = amplitude * np.sin(2 * np.pi * t / period + phase)
    window = round(frac * period / dt) * dt
    exact = sine_peak_to_peak(amplitude, period, window)
    got = M.peak_to_peak(x, dt, window)
    assert got <= exact * (1 + 1e-12)
    assert got >= exact * (1 - 0.5 * (math.pi * dt / period) ** 2) - 1e-12


def test_short_record_raises_or_uses_whole_record():
    x = np.array([0.0, 3.0, -1.0, 2.0])
    with pytest.raises(M.RecordTooShortError, match="4 samples"):
        M.peak_to_peak(x, 0.1, 1.0)
    assert issubclass(M.RecordTooShortError, ValueError)
    assert M.peak_to_peak(x, 0.1, 1.0, short="whole") == 4.0


def test_bad_inputs_are_rejected():
    with pytest.raises(M.WindowError, match="dt"):
        M.peak_to_peak(np.zeros(10), 0.0, 1.0)
    with pytest.raises(M.WindowError, match="window"):
        M.peak_to_peak(np.zeros(10), 0.1, -1.0)
    with pytest.raises(ValueError, match="non-finite"):
        M.peak_to_peak(np.array([0.0, np.nan, 1.0]), 0.1, 0.1)


# ---------------------------------------------------------------- ECSS indices


def test_ramp_mpe_rpe_pde_analytic():
    # e(t) = a t + b sampled at t_j = j dt.  Window of m samples: block k holds
    # j = k m .. k m + m - 1, mean a dt (k m + (m - 1)/2) + b, so
    # RPE_j = a dt (j mod m - (m - 1)/2), and PDE over Ts = a Ts exactly.
    a, b, dt, m = 0.3, -2.0, 0.01, 25
    n = 1010  # 40 whole windows + 10 trailing samples that are dropped
    j = np.arange(n)
    e = a * j * dt + b
    window = m * dt
    k = np.arange(n // m)
    np.testing.assert_allclose(M.mpe(e, dt, window), a * dt * (k * m + (m - 1) / 2) + b,
                               atol=1e-12)
    r = M.rpe(e, dt, window)
    assert r.shape == (40 * m,)
    np.testing.assert_allclose(r, a * dt * (j[: 40 * m] % m - (m - 1) / 2), atol=1e-12)
    np.testing.assert_allclose(M.pde(e, dt, window, 0.5), a * 0.5, atol=1e-12)
    np.testing.assert_array_equal(M.ape(e), e)


def test_rpe_plus_mpe_rebuilds_the_record():
    rng = np.random.default_rng(7)
    e = rng.normal(size=(3, 120))
    r = M.rpe(e, 1.0, 12.0).reshape(3, 10, 12)
    m = M.mpe(e, 1.0, 12.0)
    np.testing.assert_allclose(r + m[..., None], e.reshape(3, 10, 12), atol=1e-12)


def test_requirement_interpretations_differ_as_defined():
    x = np.zeros((4, 10))
    x[0, 0] = 5.0  # realisation 0 violates 1 sample in 10
    x[1, :3] = -5.0  # realisation 1 violates 3 samples in 10 (|X| is compared)
    t = M.check_requirement(x, 1.0, 0.8, "temporal")
    e = M.check_requirement(x, 1.0, 0.8, "ensemble")
    mx = M.check_requirement(x, 1.0, 0.8, "mixed")
    assert (t.probability, e.probability, mx.probability) == (0.7, 0.5, 0.9)
    assert (t.passed, e.passed, mx.passed) == (False, False, True)
    passed, p = M.check_requirement(x, 1.0, 0.5, "ensemble")
    assert passed and p == 0.5
    # signed comparison ignores the negative excursions of realisation 1
    assert M.check_requirement(x, 1.0, 0.8, "ensemble", absolute=False).probability == 0.75
    with pytest.raises(ValueError, match="interpretation"):
        M.check_requirement(x, 1.0, 0.8, "worst")


# ---------------------------------------------------------------- RMS metrics


@settings(max_examples=100, deadline=None)
@given(n=st.integers(2, 120), frac=st.floats(0, 1), seed=st.integers(0, 2**32 - 1))
def test_jitter_rms_matches_brute_force(n, frac, seed):
    rng = np.random.default_rng(seed)
    x = 3.0 + np.cumsum(rng.normal(size=n))
    m = 1 + int(frac * (n - 1))
    v = sliding_window_view(x, m)
    ref = np.sqrt(np.mean(v.var(axis=-1)))
    # Cumulative sums of squares cancel: the mean-square error is ~ n eps max|y|^2 with y
    # the mean-removed record, so the RMS error is ~ sqrt(n eps) max|y| (about 1e-7 max|y|).
    scale = np.abs(x - x.mean()).max()
    np.testing.assert_allclose(M.jitter_rms(x, 1.0, m), ref, rtol=1e-9, atol=1e-6 * scale)


def test_white_noise_jitter_is_sample_variance():
    # E[(1/m) sum (x - xbar)^2] = sigma^2 (m - 1)/m for white noise.
    rng = np.random.default_rng(11)
    sigma, m = 2.0, 8
    x = sigma * rng.normal(size=1_000_000)
    np.testing.assert_allclose(M.jitter_rms(x, 1.0, m), sigma * math.sqrt((m - 1) / m),
                               rtol=5e-3)  # standard error ~ 0.1 %


@pytest.fixture(scope="module")
def resonant_record():
    """Seeded record: 20 Hz resonance (zeta 0.2) plus a white floor, with its exact PSD.

    2e6 samples at 1 kHz; correlation time ~ 1/(2 zeta w0) = 0.02 s, so the relative
    standard error of the time-domain mean squares is ~ sqrt(2 * 0.02 / 2000) = 0.45 %,
    and 2 % is more than four standard errors.
    """
    dt, n = 1e-3, 2_000_000
    w0, zeta = 2 * np.pi * 20.0, 0.2
    b, a, _ = cont2discrete(([w0**2], [1, 2 * zeta * w0, w0**2]), dt, method="bilinear")
    b = b.ravel()
    w = np.random.default_rng(2024).normal(size=n)  # unit-variance white disturbance
    x = lfilter(b, a, w) + 0.3 * w
    f = np.linspace(0, 0.5 / dt, 100_001)
    _, h = freqz(b, a, worN=f, fs=1 / dt)
    frf = h + 0.3
    disturbance_psd = np.full(f.size, 2 * dt)  # one-sided PSD of unit white noise
    return dt, x, f, frf, disturbance_psd


@pytest.mark.parametrize("window", [0.01, 0.05, 0.2, 1.0])
def test_jitter_time_and_frequency_domain_agree(resonant_record, window):
    dt, x, f, frf, sd = resonant_record
    td = M.jitter_rms(x, dt, window)
    np.testing.assert_allclose(M.jitter_rms_from_frf(f, frf, sd, window), td, rtol=0.02)
    psd = M.response_psd(frf, sd)
    np.testing.assert_allclose(M.jitter_rms_from_psd(f, psd, window), td, rtol=0.02)
    fw, pw = M.one_sided_psd(x, dt, 16.0)  # estimated PSD of the same record
    np.testing.assert_allclose(M.jitter_rms_from_psd(fw, pw, window), td, rtol=0.02)


@pytest.mark.parametrize(("lag", "window"), [(0.005, None), (0.02, None), (0.1, None),
                                             (0.02, 0.01), (0.1, 0.01)])
def test_stability_time_and_frequency_domain_agree(resonant_record, lag, window):
    dt, x, f, frf, sd = resonant_record
    td = M.stability_rms(x, dt, lag, window=window)
    fd = M.stability_rms_from_psd(f, M.response_psd(frf, sd), lag, window, dt=dt)
    np.testing.assert_allclose(fd, td, rtol=0.02)


def test_weightings_limits():
    f = np.array([0.0, 1.0, 2.0, 1e6])
    np.testing.assert_allclose(M.jitter_weight(f, 1.0), [0.0, 1.0, 1.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(M.stability_weight(np.array([0.0, 0.5, 1.0]), 1.0),
                               [0.0, 4.0, 0.0], atol=1e-12)
    # sampled kernel tends to the continuous one as m grows
    ff = np.linspace(0, 50, 501)
    np.testing.assert_allclose(M.average_weight(ff, 0.1, dt=1e-4), M.average_weight(ff, 0.1),
                               atol=1e-6)


def test_response_psd_mimo_forms_agree():
    rng = np.random.default_rng(5)
    h = rng.normal(size=(7, 2, 3)) + 1j * rng.normal(size=(7, 2, 3))
    s = rng.uniform(1, 2, size=(7, 3))
    full = np.einsum("fk,kl->fkl", s, np.eye(3))
    np.testing.assert_allclose(M.response_psd(h, s), M.response_psd(h, full), rtol=1e-12)
    np.testing.assert_allclose(M.response_psd(h[:, 0, 0], s[:, 0]),
                               np.abs(h[:, 0, 0]) ** 2 * s[:, 0], rtol=1e-12)


# ---------------------------------------------------------------- budgets


def test_rss_and_margin_of_known_numbers():
    assert M.rss([3.0, 4.0]) == 5.0
    assert M.rss([1.0, 2.0, 2.0]) == 3.0
    np.testing.assert_allclose(M.rss([[3.0, 5.0], [4.0, 12.0]], axis=0), [5.0, 13.0])
    a, r = M.margin(5.0, 8.0)
    assert (a, r) == (3.0, 0.375)


def test_budget_lines_totals_margins_and_dominant_events():
    entries = [
        ("VNIR pointing", "SWIR", "roll", 3.0),
        ("SWIR cryocooler", "SWIR", "roll", 4.0),
        ("SAD", "SWIR", "roll", 0.0),
        {"event": "VNIR pointing", "instrument": "MISR", "axis": "pitch", "value": 12.0},
        {"event": "CERES scan", "instrument": "MISR", "axis": "pitch", "value": 5.0},
    ]
    lines = M.budget(entries, {"SWIR": 6.0, ("MISR", "pitch"): 10.0, "MISR": 100.0})
    swir, misr = lines
    assert (swir.instrument, swir.axis, swir.total) == ("SWIR", "roll", 5.0)
    assert (swir.margin, swir.margin_ratio, swir.passed) == (1.0, 1 / 6, True)
    assert [c.event for c in swir.contributions] == ["SWIR cryocooler", "VNIR pointing", "SAD"]
    np.testing.assert_allclose([c.share for c in swir.contributions], [0.64, 0.36, 0.0])
    assert misr.total == 13.0 and misr.requirement == 10.0
    assert misr.passed is False and misr.margin == -3.0
    np.testing.assert_allclose(misr.margin_percent, -30.0)
    assert misr.dominant == "VNIR pointing"
    no_req = M.budget([("a", "X", "yaw", 1.0)])[0]
    assert no_req.passed is None and math.isnan(no_req.margin)


def test_budget_rejects_duplicates_and_negative_values():
    with pytest.raises(ValueError, match="twice"):
        M.budget([("a", "X", "yaw", 1.0), ("a", "X", "yaw", 2.0)])
    with pytest.raises(ValueError, match="non-negative"):
        M.budget([("a", "X", "yaw", -1.0)])


def test_campaign_ecss_kinds_on_a_ramp():
    """e = c t sampled at dt: every ECSS index of a ramp has a closed form.  With windows
    of m = T/dt samples (whole blocks from t = 0): APE = c t_end; MPE = the mean of the
    last whole block, c dt (n_blocks m - (m + 1) / 2); RPE = the half-spread of a block,
    c dt (m - 1) / 2; PDE = the difference of two sliding means one window apart, c T."""
    from orchestrator.metrics.kinds import metric_values

    c, dt, T = 2.0, 1e-3, 0.05
    n = 1001                                   # t = 0 .. 1 s
    e = c * dt * np.arange(n)
    m = round(T / dt)
    blocks = n // m
    got = metric_values(e, dt, [("ape", None), ("mpe", T), ("rpe", T), ("pde", T)])
    want = [c * dt * (n - 1), c * dt * (blocks * m - (m + 1) / 2), c * dt * (m - 1) / 2,
            c * T]
    np.testing.assert_allclose(got, want, rtol=1e-12)
    # linear and even in e, as a budget's RSS over events assumes
    np.testing.assert_allclose(metric_values(-3 * e, dt, [("ape", None), ("pde", T)]),
                               [3 * want[0], 3 * want[3]], rtol=1e-12)


def test_compiled_window_range_against_the_definition_and_the_filters(monkeypatch):
    """The one-pass compiled maximum of window ranges against the definition (every
    window by brute force) and against the running filters it replaces, value for value;
    without the library, or for a record that is not finite, the filters answer."""
    from orchestrator.metrics import _window
    from orchestrator.metrics.peak import peak_to_peak, peak_to_peak_series

    rng = np.random.default_rng(3)
    x = rng.standard_normal((4, 400)).cumsum(axis=1)
    x[1] = np.sin(0.3 * np.arange(400))
    x[2, 100:200] = 1.5                                   # plateaus: ties in the queues
    for n in (1, 2, 3, 17, 399, 400):
        want = np.array([max(np.ptp(row[i:i + n]) for i in range(400 - n + 1)) for row in x])
        got = _window.window_range_max(x, n)
        assert got is not None and np.array_equal(got, want), n
    # a transposed view is read in place, with its strides
    xt = np.ascontiguousarray(x.T).T
    assert not xt.flags.c_contiguous
    np.testing.assert_array_equal(_window.window_range_max(xt, 17),
                                  _window.window_range_max(x, 17))
    x3 = np.stack([x, 2 * x]).transpose(0, 2, 1)      # (2, 400, 4): rows not one axis
    np.testing.assert_array_equal(
        _window.window_range_max(x3.transpose(0, 2, 1), 17),
        _window.window_range_max(np.ascontiguousarray(x3.transpose(0, 2, 1)), 17))
    dt, window = 1e-3, 0.05
    np.testing.assert_array_equal(peak_to_peak(x, dt, window),
                                  peak_to_peak_series(x, dt, window).max(axis=-1))
    y = x.copy()
    y[0, 5] = np.nan
    assert _window.window_range_max(y, 10) is None
    monkeypatch.setattr(_window, "_library", lambda: None)
    np.testing.assert_array_equal(peak_to_peak(x, dt, window),
                                  peak_to_peak_series(x, dt, window).max(axis=-1))


def test_a_campaign_command_starts_without_scipy_ndimage():
    """The running extremes' fallback (scipy.ndimage, 50 ms to import) is imported where
    it is used: the campaign and the command line load without it, and the windowed
    range it gives equals the brute force."""
    import subprocess
    import sys

    code = ("import sys, orchestrator.cli, orchestrator.campaign, orchestrator.metrics; "
            "print('scipy.ndimage' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"
    x = np.random.default_rng(4).standard_normal(50)
    want = sliding_window_view(x, 7).max(axis=1) - sliding_window_view(x, 7).min(axis=1)
    np.testing.assert_array_equal(M.peak_to_peak_series(x, 1.0, 6.0), want)
