"""Rigid elements and MPCs on g-set matrices (structfmu.nastran.rigid), and DMIG input.

Reference: the constraints written here from rigid-body kinematics (``u_b = u_a +
theta_a x r``, ``theta_b = theta_a``, in basic, each grid's DOFs in its CD frame) and
the MPC's own equation, the admissible motions as their null space
(:func:`scipy.linalg.null_space`, no choice of dependent DOFs), and the eigenvalues of
``Z^T K Z`` against ``Z^T M Z``.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as la
import scipy.sparse as sp

from structfmu import nastran as nas

XYZ = {1: (0.0, 0.0, 0.0), 2: (10.0, 0.0, 0.0), 3: (12.0, 5.0, 2.0), 4: (20.0, 0.0, 0.0),
       5: (20.0, 4.0, -3.0), 6: (30.0, 0.0, 0.0)}


def rotation():
    axis = np.ones(3) / np.sqrt(3.0)
    cx = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(0.5) * cx + (1 - np.cos(0.5)) * cx @ cx  # columns: local axes


def write_model(tmp_path, rigid=True, extra=""):
    BDF, _, OP4 = nas.pynastran()
    m = BDF(log=nas.pyn.QuietLog().log)
    R = rotation()
    m.add_cord2r(9, [0.0, 0.0, 0.0], list(R[:, 2]), list(R[:, 0]))
    for g, xyz in XYZ.items():
        m.add_grid(g, list(xyz), cd=9 if g == 3 else 0)
    m.add_spc1(1, "123456", [1])
    if rigid:
        m.add_rbe2(10, 2, "123456", [3])
        m.add_rbar(11, [4, 5], "123456", "", "", "123456")
        m.add_mpc(1, [6, 4], ["1", "6"], [1.0, -0.3])  # u6_x = 0.3 theta4_z (in per rad)
    m.write_bdf(str(tmp_path / "rigid.bdf"), size=16, enddata=True)
    if extra:
        text = (tmp_path / "rigid.bdf").read_text().replace("ENDDATA", extra + "ENDDATA")
        (tmp_path / "rigid.bdf").write_text(text)
    rng = np.random.default_rng(11)
    n = 6 * len(XYZ)
    A = rng.standard_normal((n, n))
    S = np.diag(np.tile([1e2, 1e2, 1e2, 1e3, 1e3, 1e3], len(XYZ)))  # rotations stiffer
    K = S @ (A @ A.T + n * np.eye(n)) @ S
    M = np.diag(rng.uniform(0.5, 1.5, n))
    OP4(log=nas.pyn.QuietLog().log).write_op4(str(tmp_path / "rigid.op4"),
                                              {"KGG": (6, K), "MGG": (6, M)}, is_binary=False)
    return tmp_path / "rigid.bdf", tmp_path / "rigid.op4", K, M


def write_dmig(path, K, M, names=("KAAX", "MAAX")):
    """K and M on the free DOFs (grid 1 is clamped) as symmetric DMIG cards (IFO 6, upper
    triangle, TIN 1 with 16 digits: the PARAM,EXTOUT,DMIGPCH layout) in ``path``."""
    BDF = nas.pynastran()[0]
    d = BDF(log=nas.pyn.QuietLog().log)
    dofs = [(g, c) for g in XYZ if g != 1 for c in range(1, 7)]
    idx = [6 * (g - 1) + c - 1 for g, c in dofs]
    for name, A in zip(names, (K[np.ix_(idx, idx)], M[np.ix_(idx, idx)])):
        GCj, GCi, Real = [], [], []
        for j, dj in enumerate(dofs):
            for i, di in enumerate(dofs[:j + 1]):
                if A[i, j] != 0:
                    GCj.append(dj)
                    GCi.append(di)
                    Real.append(float(A[i, j]))
        d.add_dmig(name, 6, 1, 2, 0, len(dofs), GCj, GCi, Real)
    d.write_bdf(str(path), size=16, is_double=True, enddata=False)
    return path


def reference_constraints():
    """Rows over the g-set (6 per grid, ids 1..6), native units (in, rad)."""
    R = rotation()
    frame = {g: (R if g == 3 else np.eye(3)) for g in XYZ}
    rows = []

    def col(g, c):
        return 6 * (g - 1) + c - 1

    def link(a, b):
        r = np.subtract(XYZ[b], XYZ[a])
        for k in range(6):  # equation k of b's CD components
            row = np.zeros(36)
            e = frame[b][:, k % 3]  # b's local axis in basic
            if k < 3:  # e . (u_b - u_a - theta_a x r) = 0, theta_a x r . e = theta_a . (r x e)
                for j in range(3):
                    row[col(b, j + 1)] += (frame[b].T @ frame[b])[k, j]
                    row[col(a, j + 1)] -= (frame[a].T @ e)[j]
                    row[col(a, j + 4)] -= (frame[a].T @ np.cross(r, e))[j]
            else:  # e . (theta_b - theta_a) = 0
                for j in range(3):
                    row[col(b, j + 4)] += (frame[b].T @ frame[b])[k - 3, j]
                    row[col(a, j + 4)] -= (frame[a].T @ e)[j]
            rows.append(row)

    link(2, 3)
    link(4, 5)
    row = np.zeros(36)
    row[col(6, 1)], row[col(4, 6)] = 1.0, -0.3
    rows.append(row)
    fixed = [col(1, c) for c in range(1, 7)]
    return np.array(rows), fixed


@pytest.mark.parametrize("units", ["SI", "in-lbf-s"])
def test_rbe2_rbar_mpc_applied_to_gset_matrices(tmp_path, units):
    bdf, op4, K, M = write_model(tmp_path)
    C, fixed = reference_constraints()
    free = [i for i in range(36) if i not in fixed]
    Z = la.null_space(C[:, free])
    lam = la.eigh(Z.T @ K[np.ix_(free, free)] @ Z, Z.T @ M[np.ix_(free, free)] @ Z,
                  eigvals_only=True)
    model = nas.import_nastran(bdf, units=units, op4=op4, n_modes=8, ritz="none",
                               sensors=[nas.parse_point("u3=3:2"), nas.parse_point("u6=6:1")])
    assert model.meta["n_rigid"] == 3  # RBE2 (one link), RBAR, MPC
    # well-conditioned random K: eigenvalues to 1e-10
    np.testing.assert_allclose(model.omega**2, lam[:8], rtol=1e-10)
    # a dependent grid is observed through its independent one: the sensors are not empty
    assert np.all(np.abs(model.C_e).max(axis=1) > 0)
    # and ignoring the rigid elements would give another model
    free_only = la.eigh(K[np.ix_(free, free)], M[np.ix_(free, free)], eigvals_only=True)
    assert abs(free_only[0] / lam[0] - 1) > 1e-3


def test_refused_rigid_element_is_named(tmp_path):
    bdf, op4, _, _ = write_model(tmp_path, extra="RBE3    20              6       123     1.0     "
                                                 "123     4       5\n")
    with pytest.raises(nas.NastranError, match=r"rigid element RBE3 20 cannot be applied"):
        nas.import_nastran(bdf, units="SI", op4=op4, n_modes=4, ritz="none")


def test_dependent_dof_in_an_aset_is_refused(tmp_path):
    bdf, op4, K, M = write_model(tmp_path)
    dofs = [(g, c) for g in XYZ for c in range(1, 7)]
    with pytest.raises(nas.NastranError, match=r"RBE2 10 makes grid 3 component 1 dependent, "
                                               r"but it is a row of the a-set matrices"):
        nas.import_nastran(bdf, units="SI", op4=op4, n_modes=4, ritz="none", dof_map=dofs)


def test_dmig_punch_gives_the_same_model_as_the_op4(tmp_path):
    """KAAX/MAAX as DMIG cards (PARAM,EXTOUT,DMIGPCH layout) on the free DOFs.

    TIN = 1 (single) with 16-digit values, as the OP4 case: read in double, the two
    files give the same model to round-off (float32 would differ by ~1e-8).
    """
    bdf, op4, K, M = write_model(tmp_path, rigid=False)
    write_dmig(tmp_path / "rigid.pch", K, M)
    via_dmig = nas.import_nastran(bdf, units="SI", dmig=tmp_path / "rigid.pch", n_modes=6,
                                  loads=[nas.parse_point("f=6:1", "force")])
    via_op4 = nas.import_nastran(bdf, units="SI", op4=op4, n_modes=6,
                                 loads=[nas.parse_point("f=6:1", "force")])
    np.testing.assert_allclose(via_dmig.omega, via_op4.omega, rtol=1e-12)
    np.testing.assert_allclose(np.abs(via_dmig.B_o), np.abs(via_op4.B_o), rtol=1e-8)
    assert sp.issparse(nas.read_dmig(tmp_path / "rigid.pch")["KAAX"][0])


def test_an_unsymmetric_square_dmig_is_refused(tmp_path):
    """A square DMIG (IFO 1) is taken as written, so it is checked for symmetry as an OP4
    is: one entry off its mirror by 1e-3 of the largest is one sentence naming the rows."""
    bdf, _, K, M = write_model(tmp_path, rigid=False)
    BDF = nas.pynastran()[0]
    d = BDF(log=nas.pyn.QuietLog().log)
    dofs = [(g, c) for g in XYZ if g != 1 for c in range(1, 7)]
    idx = [6 * (g - 1) + c - 1 for g, c in dofs]
    Kb = K[np.ix_(idx, idx)].copy()
    Kb[0, 1] += 1e-3 * np.abs(Kb).max()
    for name, A in (("KAAX", Kb), ("MAAX", M[np.ix_(idx, idx)])):
        GCj, GCi, Real = [], [], []
        for j, dj in enumerate(dofs):
            for i, di in enumerate(dofs):   # every entry (square, IFO 1)
                if A[i, j] != 0:
                    GCj.append(dj)
                    GCi.append(di)
                    Real.append(float(A[i, j]))
        d.add_dmig(name, 1, 1, 2, 0, len(dofs), GCj, GCi, Real)
    d.write_bdf(str(tmp_path / "bad.pch"), size=16, is_double=True, enddata=False)
    with pytest.raises(nas.NastranError, match=r"DMIG KAAX .* is not symmetric: A - A\^T "
                                               r"reaches 0.001 of its largest entry \(rows 1 "
                                               r"and 2\)"):
        nas.import_nastran(bdf, units="SI", dmig=tmp_path / "bad.pch", n_modes=6)
