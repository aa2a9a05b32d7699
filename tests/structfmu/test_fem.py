"""Truss elements against analytic references."""

import numpy as np
import pytest
import scipy.sparse as sp

from structfmu.errors import DimensionError, ModelError
from structfmu.fem import Truss, assemble
from structfmu.reduce import eigenpairs, static_compliance
from tests.structfmu.conftest import rod_chain


def test_rod_axial_frequency_converges_at_second_order():
    # Fixed-free rod: omega_1 = (pi/2) sqrt(EA / (rho A L^2)) (e.g. Rao, Vibrations, 8.4)
    EA, rho_a, L = 1e6, 2.0, 1.0
    exact = np.pi / 2 * np.sqrt(EA / (rho_a * L**2))
    ns, errs = [4, 8, 16, 32], []
    for n in ns:
        K, M = assemble(rod_chain(n, L, EA, rho_a))
        lam, _, _ = eigenpairs(K, M, 1)
        errs.append(abs(np.sqrt(lam[0]) - exact) / exact)
    slope = np.polyfit(np.log(ns), np.log(errs), 1)[0]
    assert errs[-1] < 1e-3
    assert slope == pytest.approx(-2.0, abs=0.1)  # consistent mass: O(h^2)


def test_lumped_mass_converges_from_below_and_total_mass_matches():
    EA, rho_a, L = 1e6, 2.0, 1.0
    exact = np.pi / 2 * np.sqrt(EA / (rho_a * L**2))
    tr_l = rod_chain(32, L, EA, rho_a, mass_type="lumped", fixed=False)
    tr_c = rod_chain(32, L, EA, rho_a, mass_type="consistent", fixed=False)
    for tr in (tr_l, tr_c):
        _, M = assemble(tr, free_only=False)
        ones = np.tile([1.0, 0, 0], len(tr.nodes))
        assert ones @ (M @ ones) == pytest.approx(rho_a * L, rel=1e-12)
    K, M = assemble(rod_chain(32, L, EA, rho_a, mass_type="lumped"))
    lam, _, _ = eigenpairs(K, M, 1)
    assert np.sqrt(lam[0]) < exact  # lumped mass under-estimates
    assert np.sqrt(lam[0]) == pytest.approx(exact, rel=2e-3)


def test_two_bar_truss_static_deflection():
    # Symmetric two-bar truss, apex load P down: delta = P L / (2 EA sin^2(theta))
    L, theta, EA = 2.0, np.radians(35.0), 3e7
    span = L * np.cos(theta)
    nodes = np.array([[-span, 0, 0], [span, 0, 0], [0, 0, L * np.sin(theta)]])
    tr = Truss(nodes, [[0, 2], [1, 2]], np.full(2, EA / L), np.ones(2), np.ones(3),
               fixed_dofs=np.r_[0:6, 7])  # supports, and the apex's out-of-plane DOF
    load = tr.force_channel("P", 2, (0, 0, -1))
    disp = tr.disp_channel("w", 2, (0, 0, -1))
    tr = tr.replace(loads=(load,), outputs=(disp,))
    delta = static_compliance(tr, ["P"], [disp])[0, 0]
    assert delta == pytest.approx(L / (2 * EA * np.sin(theta) ** 2), rel=1e-12)


def test_assembly_is_sparse_and_symmetric(truss10_full):
    K, M = assemble(truss10_full)
    assert sp.issparse(K) and sp.issparse(M)
    assert abs(K - K.T).max() < 1e-6 * abs(K).max()
    assert abs(M - M.T).max() < 1e-12 * abs(M).max()
    assert K.nnz < 0.2 * K.shape[0] ** 2


def test_active_member_uses_eq1_constants(truss10_full):
    for a in truss10_full.active:
        assert truss10_full.axial_stiffness[a.element] == a.stack.k_e
        assert a.stack.k_d == pytest.approx(a.stack.k_e + a.stack.ch**2 / a.stack.capacitance)
        assert a.stack.m_e == pytest.approx(a.stack.mass / 6)
        # free stroke at rated voltage reproduces the datasheet
        assert a.stack.free_stroke(a.stack.rated_voltage) == pytest.approx(a.stack.stroke)


@pytest.mark.parametrize("bad, msg", [
    (dict(elements=[[0, 5]]), "unknown node 5"),
    (dict(axial_stiffness=[1.0, 2.0]), "axial_stiffness has shape"),
    (dict(nodes=np.zeros((3, 2))), "expected (n_nodes, 3)"),
    (dict(axial_stiffness=[-1.0]), "must be positive"),
])
def test_bad_models_give_one_clear_sentence(bad, msg):
    base = dict(nodes=np.eye(3), elements=[[0, 1]], axial_stiffness=[1.0],
                element_mass=[1.0], node_mass=np.ones(3))
    base.update(bad)
    with pytest.raises((ModelError, DimensionError), match=None) as exc:
        Truss(**base)
    assert msg in str(exc.value)
    assert "\n" not in str(exc.value)


def test_unknown_node_name_suggests(truss10_full):
    with pytest.raises(ModelError, match="did you mean"):
        truss10_full.node("n1_0_-88")
