"""NASTRAN's own Ritz vectors: a SOL 103 OP2 with residual vectors (RESVEC).

No RESVEC output from NASTRAN itself is at hand (../shared/nastran has none), so the
OP2 here is SYNTHETIC, written with pyNastran's writer (structfmu.nastran.write_modes_op2,
float32 as NASTRAN writes OP2 results) from the ten-bay truss solved here the way
RESVEC builds its augmented basis: the 6 eigenvectors, then the static shapes of the
two stack forces made M-orthogonal to them and K-orthogonal among themselves (so the
OP2 lists them as two more "modes" with their generalized mass and stiffness), every
vector MAX-normalised with its generalized mass in LAMA, and the BDF's EIGRL asking
for the 6 roots.  What is tested: the importer recognises the two residual vectors,
honours the generalized masses, and gives the paper's model (6 modes + 2 Ritz
vectors, Eq. 3-8) without an OP4.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as la

from fmukit.units import INCH, LBF
from structfmu import nastran as nas
from structfmu.fem import assemble
from structfmu.models import truss10
from structfmu.reduce import reduce
from structfmu.statespace import frf

from .test_nastran import BENCH, DIAG, DIAG_GAUGE, LONG, LONG_GAUGE, TIP, assert_same_model


def resvec_op2(tmp_path, nd=6):
    truss = truss10.build()
    _, basis = reduce(truss, 6, return_basis=True)
    K, M = assemble(truss)
    phi, To = basis[:, :6], basis[:, 6:]
    Koo = To.T @ (K @ To)
    lam_r, V = la.eigh(0.5 * (Koo + Koo.T))
    vecs = np.hstack([phi, To @ V])
    lam = np.concatenate([np.sum(phi * (K @ phi), axis=0), lam_r])
    n = len(truss.nodes)
    full = np.zeros((truss.n_dof, vecs.shape[1]))
    full[truss.free_dofs] = vecs
    out = np.zeros((6 * n, vecs.shape[1]))
    out[(6 * np.arange(n)[:, None] + np.arange(3)).ravel()] = full
    # mass-normalised in the file's units (in, rad; energy lbf in), then MAX-normalised:
    # the generalized mass of v / max|v| is 1 / max|v|^2
    native = out / np.array([INCH if c < 3 else 1.0 for _ in range(n)
                             for c in range(6)])[:, None] * np.sqrt(INCH * LBF)
    gen_mass = 1.0 / np.abs(native).max(axis=0) ** 2
    bdf, _ = nas.write_truss_deck(truss, tmp_path / "t.bdf", tmp_path / "t.op4",
                                  units="in-lbf-s")
    text = bdf.read_text().replace("ENDDATA", f"EIGRL   1                       {nd}\nENDDATA")
    bdf.write_text(text)
    op2 = nas.write_modes_op2(tmp_path / "resvec.op2", lam, out, np.arange(1, n + 1),
                              units="in-lbf-s", gen_mass=gen_mass)
    return bdf, op2


def test_residual_vectors_give_the_paper_model_without_op4(tmp_path):
    bdf, op2 = resvec_op2(tmp_path)
    units = "in-lbf-s"
    with pytest.warns(nas.NastranWarning) as record:
        model = nas.import_nastran(
            bdf, units=units, op2=op2, n_modes=8,
            actuators=[nas.parse_actuator(f"{LONG}=P-243.30,name=long,gauge={LONG_GAUGE}",
                                          units),
                       nas.parse_actuator(f"{DIAG}=P-243.40,name=diag,gauge={DIAG_GAUGE}",
                                          units)],
            loads=[nas.parse_point(f"f_tip_x={TIP}:1", "force"),
                   nas.parse_point(f"f_tip_y={TIP}:2", "force")],
            sensors=[nas.parse_point(f"acc_tip_x={TIP}:1:accel"),
                     nas.parse_point(f"acc_tip_y={TIP}:2:accel")],
            los=[nas.parse_los("los_tip=" + ",".join(map(str, BENCH)))],
            damping=truss10.damping(6))
    messages = " ".join(str(w.message) for w in record)
    assert "2 of the 8 OP2 vectors are residual vectors" in messages
    assert "cannot replace the members" in messages  # the stacks are in the modes already
    assert (model.n_modes, model.n_ritz) == (6, 2)
    native = truss10.reduced()
    # float32 vectors and eigenvalues (eps 6e-8): frequencies to 1e-7, FRFs to 1e-5 of
    # peak (1/(2 zeta) = 280 at the first mode), as the modes-only OP2 test
    assert_same_model(model, native, rtol_f=1e-7, rtol_h=1e-5)
    # the static strain per stack force that modes alone miss by > 10 % (test_nastran)
    g = frf(model, [0.5], ["strain_diag"], ["fc_diag"])[0, 0, 0]
    g0 = frf(native, [0.5], ["strain_diag"], ["fc_diag"])[0, 0, 0]
    assert abs(g / g0 - 1) < 1e-5


def test_without_eigrl_range_every_vector_is_a_mode(tmp_path):
    """EIGRL ND = 8: the same vectors are all taken as eigenvectors (no Ritz block)."""
    bdf, op2 = resvec_op2(tmp_path, nd=8)
    with pytest.warns(nas.NastranWarning, match="without residual vectors"):
        model = nas.import_nastran(bdf, units="in-lbf-s", op2=op2, n_modes=8)
    assert (model.n_modes, model.n_ritz) == (8, 0)
