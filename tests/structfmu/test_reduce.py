"""Eigenvector + static Ritz reduction (Eq. 3-8)."""

import numpy as np
import pytest

from structfmu.errors import ReductionError
from structfmu.fem import ActiveMember, Truss, assemble
from structfmu.reduce import Damping, reduce, static_compliance
from structfmu.reduced import ReducedModel
from tests.structfmu.conftest import rod_chain


def test_basis_is_mass_orthonormal(truss10_full, truss10_reduced):
    model, T = truss10_reduced
    _, M = assemble(truss10_full)
    np.testing.assert_allclose(T.T @ (M @ T), np.eye(T.shape[1]), atol=1e-10)


def test_gram_schmidt_orthogonality_and_block_structure(truss10_full, truss10_reduced):
    model, T = truss10_reduced
    K, M = assemble(truss10_full)
    Te, To = T[:, :6], T[:, 6:]
    assert To.shape[1] == 2
    assert np.abs(Te.T @ (M @ To)).max() < 1e-10          # Eq. 5
    KeO = Te.T @ (K @ To)                                  # Eq. 7: off-diagonal K vanishes
    assert np.abs(KeO).max() < 1e-7 * np.abs(model.K_oo).max()
    np.testing.assert_allclose(Te.T @ (K @ Te), np.diag(model.omega**2), atol=1e-6 *
                               model.omega.max() ** 2)


def test_static_response_exact_with_ritz_not_without(truss10_full, truss10_reduced):
    model, _ = truss10_reduced
    acts = ["fc_long", "fc_diag"]
    full = static_compliance(truss10_full, acts)  # elongation per force, (2, 2)
    outs = ["elong_long", "elong_diag"]

    def reduced_static(m):
        s = m.select(acts, outs)
        Ke = np.diag(1 / s.omega**2)
        x = s.C_e @ Ke @ s.B_e
        if s.n_ritz:
            x = x + s.C_o @ np.linalg.solve(s.K_oo, s.B_o)
        return x

    np.testing.assert_allclose(reduced_static(model), full, rtol=1e-9)
    err = np.abs(reduced_static(model.without_ritz()) - full) / np.abs(full)
    assert err.max() > 0.1


def test_proportional_damping_is_eq8(truss10_full):
    m = reduce(truss10_full, 4, damping=Damping(alpha=0.3, beta=2e-5))
    np.testing.assert_allclose(m.modal_damping, 0.3 + 2e-5 * m.omega**2)
    np.testing.assert_allclose(m.D_oo, 0.3 * np.eye(2) + 2e-5 * m.K_oo)


def test_free_free_model_needs_shift_and_then_has_rigid_modes():
    # a tetrahedron floating in space: 6 rigid-body modes
    nodes = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    el = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    tr = Truss(nodes, el, np.full(6, 1e6), np.full(6, 0.5), np.full(4, 1.0))
    with pytest.raises(ReductionError, match="negative shift"):
        reduce(tr, 8, ritz=False)
    m = reduce(tr, 8, ritz=False, shift=-1.0)
    assert np.all(m.omega[:6] == 0.0)
    assert np.all(m.omega[6:] > 100)


def test_mass_not_positive_definite_is_reported():
    tr = rod_chain(4)
    tr = tr.replace(element_mass=np.zeros(4))
    with pytest.raises(ReductionError, match="mass matrix is not positive definite"):
        reduce(tr, 2, ritz=False)


def test_too_many_modes():
    with pytest.raises(ReductionError, match="only 4 free DOFs"):
        reduce(rod_chain(4), 5, ritz=False)


def test_singular_ritz_block_is_reported():
    tr = rod_chain(4)
    # two actuators on the same element give the same static shape
    tr = tr.replace(active=(ActiveMember("a", 1, None, None), ActiveMember("b", 1, None, None)))
    with pytest.raises(ReductionError, match="Ritz block is singular") as err:
        reduce(tr, 1)
    assert "drop the Ritz vector of load 'fc_" in str(err.value)


def test_a_ritz_block_left_too_few_dofs_is_refused_with_its_counts():
    """EOS with every mount leg active (69 loads) on its 780 free DOFs: 650 modes reduce
    (with their 69 Ritz vectors), 700 leave 80 DOFs for 69 static residuals, which are then
    dependent: refused in one sentence that gives the counts and a load to drop."""
    from structfmu.models import eos_testbed as et

    truss = et.build(active_legs="all")
    model = et.reduced(650, truss=truss)
    assert model.n_modes == 650 and model.n_ritz == 69
    with pytest.raises(ReductionError) as err:
        et.reduced(700, truss=truss)
    msg = str(err.value)
    assert "with 700 of the 780 free DOFs kept as eigenvectors" in msg
    assert "the static shapes of the 69 loads are linearly dependent" in msg
    assert "keep fewer modes, or drop the Ritz vector of load '" in msg


def test_unknown_ritz_input():
    with pytest.raises(ReductionError, match="no input channel"):
        reduce(rod_chain(4), 1, ritz_inputs=["fc_nope"])


def test_npz_round_trip(tmp_path, truss10_reduced):
    model, _ = truss10_reduced
    path = model.save(tmp_path / "m.npz")
    back = ReducedModel.load(path)
    for k in ("omega", "modal_damping", "B_e", "C_e", "K_oo", "D_oo", "B_o", "C_o"):
        np.testing.assert_array_equal(getattr(back, k), getattr(model, k))
    assert back.output_names == model.output_names
    assert back.output_kinds == model.output_kinds
    assert back.meta["n_ritz"] == 2
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="not a reduced-model"):
        ReducedModel.load(tmp_path / "junk.npz")


def test_the_sparse_eigensolver_gives_the_same_basis_in_every_run():
    """ARPACK's default start vector is random, so every build of a model differed in
    its last digits, and within repeated or close modes (the EOS testbed's gimbal pair)
    in the basis itself.  With the fixed start vector two runs are bit-identical."""
    from structfmu.fem import assemble
    from structfmu.models import tower
    from structfmu.reduce import eigenpairs

    truss = tower.build(10, 3, 3)
    K, M = assemble(truss)
    assert K.shape[0] > 200   # the sparse (ARPACK) path
    lam1, phi1, _ = eigenpairs(K, M, 12, truss=truss)
    lam2, phi2, _ = eigenpairs(K, M, 12, truss=truss)
    np.testing.assert_array_equal(lam1, lam2)
    np.testing.assert_array_equal(phi1, phi2)
