"""ACS design on the flexible plant (acsfmu.flexible) on a synthetic spacecraft.

The plant is built here from its continuous model: per axis a rigid body ``1/(J s^2)``
and, on roll, one lightly damped mode ``g / (J (s^2 + 2 zeta w s + w^2))`` in the
attitude (and its derivative in the rate), sampled with a zero-order hold by
python-control, the samples delayed one period (the law's computational delay).  The
loop the design reports is checked against the one computed here from that model and
the PID and filters written from their textbook forms (scipy's bilinear transform,
prewarped), not from acsfmu.law.
"""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
from scipy import signal

from acsfmu.filters import AcsConfigError
from acsfmu.flexible import AcsPlant, AxisChoice, design_on_plant, evaluate_on_plant

T = 0.1                                    # ACS period (s), Nyquist 5 Hz
J = np.array([400.0, 800.0, 1100.0])       # inertias (kg m^2)
F_MODE, ZETA = 0.8, 0.005                  # the roll mode (Hz, -)


def axis_model(j, gain):
    """Continuous (theta, rate) of one axis: rigid body plus ``gain`` times the mode."""
    w = 2 * math.pi * F_MODE
    A = np.array([[0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1], [0, 0, -w * w, -2 * ZETA * w]])
    B = np.array([[0], [1 / j], [0], [gain / j]])
    C = np.array([[1, 0, 1, 0], [0, 1, 0, 1]])
    return control.ss(A, B, C, np.zeros((2, 1)))


def synthetic_plant(gain):
    """The AcsPlant of three decoupled axes, the mode on roll only: ``x+ = Ad x + Bd u``,
    the samples ``s+ = C x`` stored and read one period later."""
    blocks = [control.c2d(axis_model(J[i], gain if i == 0 else 0.0), T, "zoh")
              for i in range(3)]
    n = 4 * 3 + 6
    Phi, Gam, R = np.zeros((n, n)), np.zeros((n, 3)), np.zeros((6, n))
    for i, d in enumerate(blocks):
        x = slice(4 * i, 4 * i + 4)
        Phi[x, x], Gam[x, i] = d.A, d.B[:, 0]
        for k in range(2):       # angle i -> sample i, rate i -> sample 3 + i
            row = 12 + (i if k == 0 else 3 + i)
            Phi[row, x] = d.C[k]
            R[i if k == 0 else 3 + i, row] = 1.0
    return AcsPlant(Phi, Gam, R, T), blocks


def prewarped(num, den, f_hz):
    """Tustin with prewarping at ``f_hz`` (scipy.signal.bilinear at the warped rate)."""
    w = 2 * math.pi * f_hz
    return signal.bilinear(num, den, fs=w / (2 * math.tan(w * T / 2)))


# python-control evaluates a state space at an array of points in one call; point by
# point (20001 calls) each call also retries a failing import (its optional slycot), which
# walks the whole sys.path: seconds alone, 15-26 s late in a test worker whose sys.path
# had grown.  Same values either way (checked: identical to the last bit).


def loop_by_hand(choice, j, d, freqs, design_phase=50.0):
    """``L = -K(z) z^-1 P(z)`` of one axis from textbook forms (negative feedback)."""
    from acsfmu.design import pid_gains_for

    kp, ki, kd = pid_gains_for(j, choice.bandwidth, design_phase, T)
    z = np.exp(2j * math.pi * np.asarray(freqs) * T)
    P = d(z)[:, 0, :].T             # (n_f, 2): one call, see above
    K = -np.stack([kp + ki * T / (z - 1), kd * np.ones_like(z)], axis=1)
    H = np.ones_like(z)
    if choice.notch_hz:
        w = 2 * math.pi * choice.notch_hz
        b, a = prewarped([1, 2 * choice.notch_zeta_num * w, w * w],
                         [1, 2 * choice.notch_zeta_den * w, w * w], choice.notch_hz)
        H = H * np.polyval(b, z) / np.polyval(a, z)
    if choice.lowpass_hz:
        w = 2 * math.pi * choice.lowpass_hz
        b, a = prewarped([w * w], [1, 2 * choice.lowpass_zeta * w, w * w], choice.lowpass_hz)
        H = H * np.polyval(np.r_[np.zeros(3 - len(b)), b], z) / np.polyval(a, z)
    return -(H * np.einsum("fk,fk->f", K, P)) / z


def test_plant_response_is_the_sampled_model():
    plant, blocks = synthetic_plant(0.5)
    f = np.array([0.01, 0.3, 0.79, 0.8, 2.0, 4.9])
    z = np.exp(2j * math.pi * f * T)
    got = plant.response(f)
    for i, d in enumerate(blocks):
        ref = d(z)[:, 0, :].T / z[:, None]                           # one period later
        np.testing.assert_allclose(got[:, [i, 3 + i], i], ref, rtol=1e-9, atol=1e-14)
    assert abs(got[:, 0, 1]).max() == 0 and abs(got[:, 1, 0]).max() == 0
    modes = plant.modes()
    assert len(modes) == 1
    # the sampled pole at the damped frequency
    np.testing.assert_allclose(modes[0], (F_MODE * math.sqrt(1 - ZETA**2), ZETA), rtol=1e-9)


def test_gain_stabilised_mode_against_the_loop_computed_by_hand():
    plant, blocks = synthetic_plant(0.5)
    d = design_on_plant(plant, J, bandwidths=(0.1, 0.02), steps=9, phase_stabilise=False)
    roll = d.axes[0]
    assert d.stable and all(a.ok for a in d.axes)
    (mode,) = roll.modes
    assert mode.how == "gain" and mode.margin >= 6.0
    # the peak near the mode and the rigid-body crossover, computed here
    fm = np.linspace(F_MODE * (1 - 3 * ZETA), F_MODE * (1 + 3 * ZETA), 2001)
    L = loop_by_hand(roll.choice, J[0], blocks[0], fm)
    peak = 20 * np.log10(np.abs(L).max())
    assert peak <= -6.0
    np.testing.assert_allclose(mode.peak_db, peak, atol=0.05)    # grid vs dense grid
    f = np.geomspace(1e-3, 1.0, 20001)
    L = loop_by_hand(roll.choice, J[0], blocks[0], f)
    k = np.flatnonzero((np.abs(L[:-1]) >= 1) & (np.abs(L[1:]) < 1))[0]
    pm = 180 - abs(math.degrees(np.angle(L[k])))
    np.testing.assert_allclose(roll.crossover_hz, f[k], rtol=2e-3)
    np.testing.assert_allclose(roll.phase_margin, pm, atol=0.05)
    assert roll.phase_margin >= 30.0
    # no design of the space at a higher crossover passes: the next one up fails
    higher = [b for b in d.searched["bandwidths_hz"] if b > roll.choice.bandwidth * 1.0001]
    if higher:
        up = evaluate_on_plant(plant, J, [AxisChoice(higher[-1]), d.axes[1].choice,
                                          d.axes[2].choice], phase_stabilise=False)
        assert not up.axes[0].ok


def test_pitch_and_yaw_rigid_bodies_take_the_highest_crossover():
    plant, blocks = synthetic_plant(0.5)
    d = design_on_plant(plant, J, bandwidths=(0.1, 0.02), steps=9)
    for i, a in enumerate(d.axes[1:], start=1):
        assert a.choice.bandwidth == pytest.approx(0.1)
        # the roll mode is listed in every axis's loop; here |L| is the rigid body's there
        (m,) = a.modes
        fm = np.linspace(m.freq_hz * (1 - 3 * ZETA), m.freq_hz * (1 + 3 * ZETA), 201)
        ref = 20 * np.log10(np.abs(loop_by_hand(a.choice, J[i], blocks[i], fm)).max())
        assert m.how == "gain"
        np.testing.assert_allclose(m.peak_db, ref, atol=1e-3)
        # the rigid-body design: 50 deg shaped, delay compensated (acsfmu.design)
        assert a.phase_margin == pytest.approx(50.0, abs=1.0)
    assert d.parameters["bandwidth_y"] == pytest.approx(0.1)
    assert 0 < d.disk_alpha < 2


def test_a_mode_that_cannot_be_stabilised_is_refused_in_one_sentence():
    plant, blocks = synthetic_plant(2.0)
    space = dict(bandwidths=(0.1, 0.05), steps=3, lowpass_ratios=(4.0,), notch_hz=(2.0,))
    with pytest.raises(AcsConfigError) as err:
        design_on_plant(plant, J, phase_stabilise=False, **space)
    msg = str(err.value)
    assert msg.startswith("ACS design: roll: the 0.8 Hz mode keeps ")
    assert "(bandwidth 0.05-0.1 Hz, notch and low-pass (4 x crossover) tried; 6 dB " \
           "requested); lower the requested margin or add damping" in msg
    assert msg.count(". ") == 0
    # the refusal is right: by hand, no design of that space keeps 6 dB at the mode
    fm = np.linspace(F_MODE * (1 - 3 * ZETA), F_MODE * (1 + 3 * ZETA), 401)
    best = -np.inf
    for bw in np.geomspace(0.1, 0.05, 3):
        for notch in ((0.0, 0.05, 0.5), (2.0, 0.02, 0.7), (2.0, 0.02, 0.3)):
            for lp in (0.0, 4 * bw):
                c = AxisChoice(bw, *notch, lp, 0.7)
                peak = 20 * np.log10(np.abs(loop_by_hand(c, J[0], blocks[0], fm)).max())
                best = max(best, -peak)
    assert best < 6.0
    stated = float(msg.split("keeps ")[1].split(" dB")[0])
    assert stated <= best + 0.05


class _Untouchable:
    """A plant that fails any computation: the refusals come first."""

    period = T

    def __getattr__(self, name):
        raise AssertionError(f"the plant's {name} was read before the request was checked")


@pytest.mark.parametrize("kwargs, words", [
    ({"gain_margin_db": -1.0}, "gain margin -1 dB is below 0 dB"),
    ({"phase_margin": 0.0}, "phase margin 0 deg is outside (0, 90)"),
    ({"phase_margin": 90.0}, "phase margin 90 deg is outside (0, 90)"),
    ({"notch_hz": (5.0,)}, "notch centre 5 Hz is at or above the ACS's Nyquist frequency 5 Hz"),
    ({"antialias": (6.0, 0.7)}, "anti-alias corner 6 Hz is at or above"),
    ({"bandwidths": (5.5, 0.01)}, "bandwidth 5.5 Hz is at or above"),
    ({"disk_margin_db": -2.0}, "disk margin -2 dB is below 0 dB"),
])
def test_bad_requests_are_refused_before_any_computation(kwargs, words):
    with pytest.raises(AcsConfigError, match="^ACS design: ") as err:
        design_on_plant(_Untouchable(), J, **kwargs)
    assert words in str(err.value)
