"""The ten-bay truss designs on the real reduced plant (structfmu.models.truss10)."""

import control
import numpy as np
import pytest

from ctrlfmu import designs
from ctrlfmu.analysis import closed_loop
from structfmu.models import truss10


@pytest.fixture(scope="module")
def plants():
    return {"diag": truss10.plant("diag"), "long": truss10.plant("long")}


def test_stored_plant_gains_match_the_model(plants):
    assert abs(control.dcgain(plants["diag"])) == pytest.approx(designs.DIAG_PLANT_GAIN, rel=1e-3)
    assert abs(control.dcgain(plants["long"])) == pytest.approx(designs.LONG_PLANT_GAIN, rel=1e-3)


@pytest.mark.parametrize("act, fn", [("diag", designs.truss10_strain_diag),
                                    ("long", designs.truss10_strain_long)])
def test_default_design_is_stable_alone_on_its_plant(plants, act, fn):
    # The stored tuning is chosen on the decay with both loops and both amplifiers in
    # the loop (tests/orchestrator/test_analysis.py); each law alone on its own
    # member's voltage-to-strain plant must still be a stable loop.
    poles = closed_loop(plants[act], fn()).poles()
    assert np.all(np.abs(poles) < 1)


def test_dc_gain_sign_would_destabilise(plants):
    # with the DC-gain sign (ignoring the zero below the mode) the loop is unstable
    law = designs.virtual_absorber(8.4, float(control.dcgain(plants["diag"])),
                                   **designs.TRUSS10_DIAG)
    assert np.any(np.abs(closed_loop(plants["diag"], law).poles()) >= 1)
