"""Generated lattice towers: rigid, the right size, and a beam when slender."""

import numpy as np
import pytest
import scipy.linalg as la

from structfmu.errors import ModelError
from structfmu.fem import assemble
from structfmu.models import tower
from structfmu.reduce import eigenpairs

# first root of 1 + cos(b) cosh(b) = 0: cantilever, omega_1 = b^2 sqrt(EI / (mu L^4))
# (Blevins, Formulas for Natural Frequency and Mode Shape, table 8-1)
BETA1 = 1.8751040687


@pytest.mark.parametrize("n_bays, nx, ny, n_active",
                         [(1, 2, 2, 4), (3, 3, 2, 4), (4, 3, 3, 0), (2, 4, 3, 2), (2, 2, 5, 1)])
def test_no_mechanism_and_dof_count(n_bays, nx, ny, n_active):
    truss = tower.build(n_bays, nx, ny, n_active=n_active)
    K, _ = assemble(truss)
    assert K.shape[0] == 3 * (nx * ny * n_bays + n_active)
    assert K.shape[0] == tower.n_free_dofs(n_bays, nx, ny, n_active)
    w = la.eigvalsh(K.toarray())
    # positive definite, and not by round-off: the softest direction keeps a fair share
    # of the stiffest (a mechanism would sit at 1e-16 of it)
    assert w[0] > 1e-6 * w[-1]


def test_member_counts_per_family():
    nx, ny, n_bays = 4, 3, 5
    fam = tower.members(nx, ny, n_bays)
    assert len(fam["longeron"]) == nx * ny * n_bays
    assert len(fam["batten"]) == ((nx - 1) * ny + nx * (ny - 1)) * n_bays
    assert len(fam["plane_diagonal"]) == (nx - 1) * (ny - 1) * n_bays
    assert len(fam["face_diagonal"]) == ((nx - 1) * ny + nx * (ny - 1)) * n_bays
    # no member twice
    all_ = np.sort(np.concatenate(list(fam.values())), axis=1)
    assert len(np.unique(all_, axis=0)) == len(all_)


def test_bays_for_reaches_the_requested_size():
    n = tower.bays_for(100_000, 10, 10)
    assert tower.n_free_dofs(n, 10, 10) >= 100_000 > tower.n_free_dofs(n - 1, 10, 10)


def _first_frequency_error(n_bays, nx=2, ny=2):
    truss = tower.build(n_bays, nx, ny)
    K, M = assemble(truss)
    lam, _, _ = eigenpairs(K, M, 1)
    beam = tower.equivalent_beam(nx, ny, n_bays)
    f_eb = BETA1**2 / (2 * np.pi) * np.sqrt(beam["EI_y"] / (beam["mu"] * beam["length"]**4))
    return np.sqrt(lam[0]) / (2 * np.pi) / f_eb - 1.0


def test_first_bending_frequency_matches_euler_bernoulli_for_a_slender_tower():
    # 40 bays on a 1-bay-wide square section (slenderness 40): the lattice's shear
    # flexibility, the mass lumped at the planes and the stiffer first bay with the
    # stacks leave about 1 % (measured -0.9 %)
    assert abs(_first_frequency_error(40)) < 0.03


def test_euler_bernoulli_error_shrinks_with_slenderness():
    # the shear (Timoshenko) correction goes like (width / height)^2: going from 20 to
    # 80 bays cuts the error at least 4-fold (measured 2.5 % -> 0.4 %)
    errors = [abs(_first_frequency_error(n)) for n in (20, 40, 80)]
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < errors[0] / 4


def test_ten_thousand_dof_tower_assembles_with_mass_and_rigid_body_checks():
    n_bays = tower.bays_for(10_000, 6, 6)
    truss = tower.build(n_bays, 6, 6)
    K, M = assemble(truss)
    assert K.shape == M.shape == (tower.n_free_dofs(n_bays, 6, 6),) * 2
    assert K.shape[0] >= 10_000
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()
    # unconstrained: total mass in each direction, and no force for a rigid translation
    K_all, M_all = assemble(truss, free_only=False)
    total = truss.node_mass.sum() + truss.element_mass.sum()
    for d in range(3):
        e = np.zeros(truss.n_dof)
        e[d::3] = 1.0
        np.testing.assert_allclose(e @ (M_all @ e), total, rtol=1e-12)
        assert np.abs(K_all @ e).max() <= 1e-9 * abs(K_all).max()


def test_outputs_and_inputs_name_the_active_members():
    truss = tower.build(3, 3, 3, n_active=4)
    inputs = [c.name for c in truss.input_channels]
    assert inputs == ["f_tip_x", "f_tip_y", "fc_a1", "fc_a2", "fc_a3", "fc_a4"]
    outputs = [c.name for c in truss.outputs]
    assert outputs[:4] == ["strain_a1", "strain_a2", "strain_a3", "strain_a4"]
    assert "los_tip_pitch" in outputs
    # the stacks are the corner longerons of the first bay, from the fixed base
    for a in truss.active:
        n1, _ = truss.elements[a.element]
        assert truss.nodes[n1][2] == 0.0
        assert truss.axial_stiffness[a.element] == pytest.approx(a.stack.k_e)


@pytest.mark.parametrize("kwargs", [dict(n_bays=0), dict(n_bays=2, nx=1),
                                    dict(n_bays=2, n_active=5), dict(n_bays=2, bay=0.05)])
def test_bad_sizes_are_refused(kwargs):
    with pytest.raises(ModelError):
        tower.build(**kwargs)
