"""The ten-bay truss designs on the real reduced plant (structfmu.models.truss10)."""

import control
import numpy as np
import pytest

from ctrlfmu import designs
from ctrlfmu.analysis import closed_loop, mode_damping, optimise_gain
from structfmu.models import truss10


@pytest.fixture(scope="module")
def plants():
    return {"diag": truss10.plant("diag"), "long": truss10.plant("long")}


def test_stored_plant_gains_match_the_model(plants):
    assert abs(control.dcgain(plants["diag"])) == pytest.approx(designs.DIAG_PLANT_GAIN, rel=1e-3)
    assert abs(control.dcgain(plants["long"])) == pytest.approx(designs.LONG_PLANT_GAIN, rel=1e-3)


@pytest.mark.parametrize("act, mode, fn", [("diag", 8.4, designs.truss10_strain_diag),
                                           ("long", 9.5, designs.truss10_strain_long)])
def test_default_design_is_the_optimum_and_damps_the_mode(plants, act, mode, fn):
    law = fn()
    res = optimise_gain(plants[act], law, mode, gain_range=(0.1, 10), n_grid=41)
    # the stored loop gain is the optimum of the damping objective (gain factor ~1)
    assert res.gain == pytest.approx(1.0, rel=0.05)
    # the mode's own closed-loop damping is at least ten times the open loop's
    poles = closed_loop(plants[act], law).poles()
    f_n, zeta = mode_damping(poles, law.dt)
    near = (f_n > 0.7 * mode) & (f_n < 1.4 * mode)
    assert zeta[near].min() > 10 * res.open_loop_damping


def test_dc_gain_sign_would_destabilise(plants):
    # with the DC-gain sign (ignoring the zero below the mode) the loop is unstable
    law = designs.virtual_absorber(8.4, float(control.dcgain(plants["diag"])),
                                   **designs.TRUSS10_DIAG)
    assert np.any(np.abs(closed_loop(plants["diag"], law).poles()) >= 1)
