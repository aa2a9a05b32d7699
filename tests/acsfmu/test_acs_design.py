"""PID design on the rigid body J s^2: crossover, margins, bandwidth."""

import numpy as np
import pytest

from acsfmu.design import design_axis, design_pid, discrete_loop, loop_margins, pid_gains_for
from acsfmu.pid import AcsConfigError


@pytest.mark.parametrize("inertia", [100.0, 7600.0, 36000.0])
@pytest.mark.parametrize("bandwidth", [0.02, 0.1, 0.3])
def test_sampled_loop_crosses_over_at_requested_bandwidth(inertia, bandwidth):
    d = design_axis(inertia, bandwidth, phase_margin=50.0, sample_time=0.1)
    # requirement: within 20 %; the delay-compensated design is within 1 %
    assert abs(d.crossover / bandwidth - 1) < 0.01
    assert d.phase_margin > 30.0
    assert abs(d.phase_margin - 50.0) < 1.0
    assert d.gain_margin > 2.0
    # closed-loop -3 dB frequency of a 50 deg margin loop lies 1.3-2x above crossover
    assert 1.3 < d.bandwidth / d.crossover < 2.0


def test_continuous_design_equations():
    # |C(j wc)| = J wc^2 and arg C(j wc) = phase margin when no sampling lag is added
    J, fc, pm = 500.0, 0.1, 45.0
    kp, ki, kd = pid_gains_for(J, fc, pm, sample_time=0.0)
    wc = 2 * np.pi * fc
    c = kp + ki / (1j * wc) + kd * 1j * wc
    np.testing.assert_allclose(abs(c), J * wc**2, rtol=1e-12)
    np.testing.assert_allclose(np.degrees(np.angle(c)), pm, rtol=1e-12)


def test_undercompensated_design_loses_the_sampling_lag():
    # without delay compensation the sampled loop's margin drops by ~1.5 wc T
    kp, ki, kd = pid_gains_for(1000.0, 0.1, 50.0, sample_time=0.0)
    _, pm, _ = loop_margins(discrete_loop(1000.0, kp, ki, kd, 0.1))
    lag = np.degrees(1.5 * 2 * np.pi * 0.1 * 0.1)
    assert abs((50.0 - pm) - lag) < 1.0


def test_design_pid_three_axes():
    gains, axes = design_pid([7600.0, 36000.0, 36000.0])
    np.testing.assert_allclose(gains.kp[1] / gains.kp[0], 36000.0 / 7600.0)
    assert len(axes) == 3 and all(a.phase_margin > 30 for a in axes)


def test_design_rejects_bandwidth_too_high_for_rate():
    with pytest.raises(AcsConfigError, match="too high for sample time"):
        pid_gains_for(100.0, bandwidth=2.0, sample_time=0.1)
