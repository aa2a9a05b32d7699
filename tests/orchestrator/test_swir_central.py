"""The central SWIR law (one LQG on the twelve stack strains), checked on the linear model
against independent facts: the separation principle, and where its information comes from."""

import numpy as np
import pytest

from orchestrator.analysis.margins import spectral_radius, without_states
from orchestrator.experiments import swir_isolation as sw

pytestmark = pytest.mark.paper   # the paper's experiments' designs: make test-full


@pytest.fixture(scope="module")
def plant():
    return sw.linear_plant()


def test_closed_loop_poles_are_the_lqg_design_poles(plant):
    # separation principle: the loop the co-simulation runs (closed_loop: the law in
    # Eq. 11 form, the stack FMU's sample) has exactly the regulator and predictor poles
    # of the design, plus twelve at zero (the law's held output repeats -K xh).  A wrong
    # timing (one sample more or less) or sign would move every pole.
    g = sw.central_gains(plant)
    law = sw.central_law(plant)
    Aa, Ba, Ca, K, L = (g[k] for k in ("Aa", "Ba", "Ca", "K", "L"))
    want = np.concatenate([np.linalg.eigvals(Aa - Ba @ K), np.linalg.eigvals(Aa - L @ Ca),
                           np.zeros(len(sw.LEGS))])
    got = np.linalg.eigvals(without_states(sw.closed_loop(plant, law, 1.0)[0],
                                           plant.rigid_states))
    assert len(got) == len(want)
    # match each wanted pole to its nearest computed one; the cluster at the origin (the
    # delay states: a defective eigenvalue, which round-off spreads by its root) by count
    small = 1e-3
    assert (np.abs(got) < small).sum() == (np.abs(want) < small).sum()
    for p in want[np.abs(want) >= small]:
        assert np.abs(got - p).min() < 1e-7
    assert spectral_radius(Aa - Ba @ K) < 1 and spectral_radius(Aa - L @ Ca) < 1


def test_subsets_read_and_drive_only_their_legs(plant):
    vnir, swir = sw.LEGS[6:], sw.LEGS[:6]
    law = sw.central_law(plant, q=0.0, sensors=vnir, actuators=swir)
    assert law.n_inputs == law.n_outputs == len(sw.LEGS)
    assert not np.any(law.B[:, :6]) and not np.any(law.D[:, :6])     # SWIR strains unread
    assert not np.any(law.C[6:]) and not np.any(law.D[6:])           # VNIR stacks idle
    # the information the SWIR legs need is in the VNIR legs' strains (they carry the
    # disturbance wrench): from them alone, SWIR pitch still falls by half
    off = sw.simulate_linear(plant, stop=3.5)
    on = sw.simulate_linear(plant, law, 1.0, stop=3.5)
    jo, jn = sw.jitter(off, "swir", ""), sw.jitter(on, "swir", "")
    assert 100 * (1 - jn["pitch"] / jo["pitch"]) >= 50.0
    assert sw.mimo_gain_margin(plant, law, 1.0) >= 6.0


def test_closed_loop_refuses_a_law_of_the_wrong_size(plant):
    law = sw.central_law(plant)
    small = type(law)(law.A, law.B[:, :3], law.C[:3], law.D[:3, :3], law.dt)
    with pytest.raises(ValueError, match="one per leg"):
        sw.closed_loop(plant, small, 1.0)


def test_unknown_variant_is_refused_in_one_sentence(tmp_path):
    with pytest.raises(ValueError, match="swir-isolation takes one of decentralized, central"):
        sw.run(tmp_path, quick=True, variant="centre")
