"""The testbed's instruments and the stacks' servo loops (testbed_instruments), each
against an analytic reference or an independent computation."""

import numpy as np
import pytest

from fmukit.units import ARCSEC
from orchestrator.experiments import testbed_design as td
from orchestrator.experiments import testbed_instruments as ti


def test_optical_scoring_filters_at_its_bandwidth_and_reads_whole_steps():
    t = np.arange(0.0, 2.0, 1e-3)
    # a 200 Hz line through a 2nd-order Butterworth at 100 Hz: |H| = 1 / sqrt(1 + 2^4)
    # (analog prototype; the bilinear map at 1 kHz prewarps the cut-off: at 200 Hz the
    # digital filter's gain is that of the analog one at tan(pi f dt)/tan(pi fc dt))
    x = 10 * ARCSEC * np.sin(2 * np.pi * 200.0 * t)
    y = ti.optical_scoring(t, x, resolution=0.0)
    ratio = np.tan(np.pi * 200e-3) / np.tan(np.pi * 100e-3)
    want = 1 / np.sqrt(1 + ratio ** 4)
    got = np.sqrt(2 * np.mean(y[t > 0.5] ** 2)) / (10 * ARCSEC)
    assert got == pytest.approx(want, rel=1e-3)
    # below half a step the reading is zero; a constant 0.3 arcsec reads one 0.2 step
    assert not ti.optical_scoring(t, 0.09 * ARCSEC * np.sin(2 * np.pi * 22 * t)).any()
    z = ti.optical_scoring(t, np.full_like(t, 0.3 * ARCSEC))
    assert z[-1] == pytest.approx(0.2 * ARCSEC) and set(np.round(z / ARCSEC, 9)) <= {0.0, 0.2, 0.4}


@pytest.mark.paper
def test_servo_holds_the_commanded_expansion_and_the_analog_plant_is_the_sampled_one(
        suite_fmu_dir):
    """The servo loop against a first-order lag at its crossover, and the analog plant
    without it against linear_plant; a servo of 200 Hz is unstable on this structure."""
    model = td.linear_model(suite_fmu_dir)
    f = np.array([2.0, 22.0, 44.0, 66.0, 10.0])
    servo = ti.servo_plant(model, 100.0, extra_outputs=["elong_iso3"])
    H = td.plant_frf(servo, f)
    # below its crossover the servo holds the stack's expansion at 0.4 um per volt
    # commanded (an integrator: no steady error), and it follows as a first-order lag at
    # its crossover: at 10 Hz -atan(10 / 100) = -5.7 deg beyond the strut's own response
    # to a command (the hold's half sample and the amplifier; quasi-static there)
    e = H[:, -1, 2] / ti.ISOLATOR_STROKE_PER_VOLT
    assert abs(e[0]) == pytest.approx(1.0, abs=0.01)
    open_ = td.plant_frf(ti.servo_plant(model, None, extra_outputs=["elong_iso3"]), f)
    lag = np.degrees(np.angle(H[-1, -1, 2] / open_[-1, -1, 2]))
    assert lag == pytest.approx(-np.degrees(np.arctan(0.1)), abs=0.5)
    # without the servo the analog plant is linear_plant with the amplifier continuous
    # instead of the step-mean force: they differ by less than what a held mean misses of
    # a line, (omega h)^2 / 12 (docs/coupling.md): 1.6e-3 at 22 Hz, 1.4e-2 at 66 Hz
    G = td.plant_frf(td.linear_plant(model), f)
    bound = (2 * np.pi * f[1:4] * td.DT) ** 2 / 12
    for j in (6, 7):
        assert np.all(np.abs(open_[1:4, j, 2] / G[1:4, j, 2] - 1) < bound)
        # the disturbance path does not pass through an amplifier: the same to round-off
        np.testing.assert_allclose(open_[1:4, j, 3], G[1:4, j, 3], rtol=1e-8)
    # the servo loop alone (the law open): stable at 100 Hz, unstable at 200 Hz
    radius = {hz: np.abs(np.linalg.eigvals(ti.servo_plant(model, hz).A)).max()
              for hz in (100.0, 200.0)}
    assert radius[100.0] < 1 + 1e-8 and radius[200.0] > 1.01
