"""Craig-Bampton matrices from an OP2 (OUTPUT2 matrix data blocks) against the OP4 path.

No OP2 with matrix data blocks from NASTRAN itself is at hand, so the OP2 here is
**synthetic**: the real superelement's KAA, MAA (and its other matrices: PA, VA, MUG1,
MUG1B, the 1 x 1 placeholders), read from its real OP4 (../shared/nastran/
superelement_n11), written by :func:`structfmu.nastran.writers.write_matrices_op2` into
OUTPUT2 matrix data blocks (pyNastran 1.4.1 has no writer for them) and read back by
pyNastran's own OP2 reader.  The same matrices must give the same model as the OP4.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.sparse as sp

from structfmu import nastran as nas
from tests.support.nastran_data import nastran_data
from structfmu.nastran.writers import write_matrices_op2

SE = nastran_data() / "superelement_n11"
PCH, OP4 = SE / "se_test_n11.pch", SE / "se_test_n11.op4"
pytestmark = pytest.mark.skipif(not OP4.is_file(), reason=f"real NASTRAN files not at {SE}: set "
                                "JITTERFMU_NASTRAN_DATA to the shared/nastran folder")

FREE = dict(units="SI", n_modes=12, shift=-1e3, boundary="free",
            loads=[nas.parse_point("fx=20110010:1", "force")],
            sensors=[nas.parse_point("ux=20110038:1:accel")])
FIXED = dict(units="SI", n_modes=39, boundary="fixed", ritz="none",
             sensors=[nas.parse_point("q1=20111101:0"), nas.parse_point("q7=20111107:0")])


@pytest.fixture(scope="module")
def op4_mats():
    return nas.read_op4(OP4)


@pytest.fixture(scope="module")
def se_op2(op4_mats, tmp_path_factory):
    """Every real matrix of the OP4 as an OUTPUT2 data block, in the OP4's order."""
    path = tmp_path_factory.mktemp("se_op2") / "se_test_n11.op2"
    return write_matrices_op2(path, {k: v.real for k, v in op4_mats.items()})


def quiet(**kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", nas.NastranWarning)
        return nas.import_nastran(PCH, **kw)


def residues(model):
    """Per mode, the sign-free product C_e[:, k] B_e[k, :] (outputs x inputs)."""
    return np.einsum("ok,ki->koi", model.C_e, model.B_e)


def shapes(model):
    """C_e with each mode's sign fixed by its largest output (mode shapes at the sensors)."""
    C = np.asarray(model.C_e, float)
    k = np.argmax(np.abs(C), axis=0)
    return C * np.sign(C[k, np.arange(C.shape[1])])


def assert_same(a, b, rtol):
    np.testing.assert_allclose(b.omega, a.omega, rtol=rtol, atol=0)
    for x, y in ((residues(a), residues(b)), (shapes(a), shapes(b)), (a.K_oo, b.K_oo),
                 (a.C_o @ a.B_o, b.C_o @ b.B_o)):
        assert x.shape == y.shape
        if x.size:
            np.testing.assert_allclose(y, x, rtol=0, atol=rtol * np.abs(x).max())


def test_op2_matrix_blocks_read_back_as_written(op4_mats, se_op2):
    """pyNastran's OP2 reader gives the OP4's values exactly, in double precision."""
    op2 = nas.modes.load_op2(se_op2)
    mats = nas.matrices.op2_matrices(op2, se_op2)
    assert set(mats) == set(op4_mats) and mats.single == []
    for name in ("KAA", "MAA", "MUG1", "PA"):
        assert mats[name].dtype == np.float64
        assert abs(mats[name] - op4_mats[name].real).max() == 0.0, name


def test_superelement_from_op2_equals_op4_free_and_fixed(se_op2):
    """Auto-detected KAA/MAA (the square K*/M* of the a-set's size; MUG1 and the 1 x 1
    placeholders left alone): frequencies, modal residues and the Ritz block equal to the
    OP4 path's to 1e-12 (the same float64 values go into the same reduction)."""
    for kw in (FREE, FIXED):
        ref = quiet(op4=OP4, **kw)
        got = quiet(op2=se_op2, **kw)
        assert_same(ref, got, 1e-12)
        assert got.meta["source"]["op2_matrices"] == ["KAA", "MAA"]
        assert got.meta["n_dof"] == ref.meta["n_dof"] == 105
    free = quiet(op2=se_op2, **FREE)
    assert np.sum(free.omega == 0) == 6 and free.n_ritz == 1
    fixed = quiet(op2=se_op2, **FIXED)
    np.testing.assert_allclose(fixed.frequencies_hz[:3], [365.260, 370.233, 381.422],
                               rtol=2e-6)  # the README's direct eigen solution of the q-set


def test_single_precision_op2_is_warned(op4_mats, tmp_path):
    """Type-1 (float32) blocks are read as stored and the import says so."""
    path = write_matrices_op2(tmp_path / "se1.op2", {"KAA": op4_mats["KAA"].real,
                                                     "MAA": op4_mats["MAA"].real},
                              precision="single")
    with pytest.warns(nas.NastranWarning) as record:
        model = nas.import_nastran(PCH, op2=path, **FIXED)
    said = " ".join(str(w.message) for w in record)
    for name in ("KAA", "MAA"):
        assert f"matrix {name} in OP2 " in said and "is single precision" in said
    ref = quiet(op4=OP4, **FIXED)
    # float32 entries (6e-8) on a q-set of condition ~1e3 in K and M: 1e-5 covers it
    np.testing.assert_allclose(model.omega, ref.omega, rtol=1e-5)
    assert np.max(np.abs(model.omega / ref.omega - 1)) > 1e-12  # it is not the double data


def test_cli_reads_the_op2_matrices(se_op2, tmp_path, capfd):
    from orchestrator.cli import main
    from orchestrator.cli._options import shown

    out = tmp_path / "se.npz"
    rc = main(["import-nastran", str(PCH), "--op2", str(se_op2), "--units", "SI",
               "--modes", "39", "--boundary", "fixed", "--ritz", "none",
               "--sensor", "q1=20111101:0", "--out", str(out)])
    captured = capfd.readouterr()
    assert rc == 0, captured.err
    assert captured.err.splitlines() == [
        f"jitterfmu: import-nastran {shown(PCH)}: reading the deck and the OP2 file, reducing "
        "to 39 modes"] and "39 modes (365.3-1976 Hz)" in captured.out


# -- what is missing or wrong: one sentence each ------------------------------------------

def test_op2_without_the_mass_matrix_names_it(op4_mats, tmp_path):
    path = write_matrices_op2(tmp_path / "k_only.op2", {"KAA": op4_mats["KAA"].real,
                                                        "PA": op4_mats["PA"].real})
    with pytest.raises(nas.NastranError, match=r"has no mass matrix MAA \(it has KAA, PA\); "
                                               r"write the stiffness and the mass .*OUTPUT2"):
        quiet(op2=path, **FIXED)


def test_op2_without_matrices_or_modes_says_what_to_write(op4_mats, tmp_path):
    path = write_matrices_op2(tmp_path / "pa.op2", {"PA": op4_mats["PA"].real,
                                                    "MUG1": op4_mats["MUG1"].real})
    with pytest.raises(nas.NastranError, match=r"has neither eigenvectors nor stiffness and mass "
                                               r"matrices; rerun .*OUTPUT2 KAA,MAA"):
        quiet(op2=path, **FIXED)
    with pytest.raises(nas.NastranError, match=r"has no stiffness matrix KXX \(it has PA, MUG1\)"):
        quiet(op2=path, k_name="KXX", m_name="MUG1", **FIXED)


def test_op2_matrices_of_the_wrong_size(op4_mats, tmp_path):
    K, M = op4_mats["KAA"].real.tocsc(), op4_mats["MAA"].real.tocsc()
    small = write_matrices_op2(tmp_path / "small.op2", {"KAA": K[:100, :100],
                                                        "MAA": M[:100, :100]})
    with pytest.raises(nas.NastranError, match=r"the matrices of OP2 .* have 100 rows, but .* "
                                               r"g-set of 105 DOFs .* a-set .* of 105"):
        quiet(op2=small, **FIXED)
    mixed = write_matrices_op2(tmp_path / "mixed.op2", {"KAA": K, "MAA": M[:100, :100]})
    with pytest.raises(nas.NastranError, match=r"stiffness matrix KAA is 105 x 105 but mass "
                                               r"matrix MAA is 100 x 100"):
        quiet(op2=mixed, **FIXED)


def test_unsymmetric_stiffness_is_refused(op4_mats, tmp_path):
    K = op4_mats["KAA"].real.tolil()
    K[70, 80] = K[70, 80] + 1e-3 * abs(op4_mats["KAA"]).max()  # a q-set coupling, one side
    path = write_matrices_op2(tmp_path / "skew.op2", {"KAA": K.tocsc(),
                                                      "MAA": op4_mats["MAA"].real})
    with pytest.raises(nas.NastranError, match=r"stiffness matrix KAA in .* is not symmetric: "
                                               r"A - A\^T reaches 0.001 of its largest entry "
                                               r"\(rows 71 and 81\)"):
        quiet(op2=path, **FIXED)


def test_dmig_form_op2_matrix_is_refused(op4_mats, se_op2, monkeypatch):
    """A MATPOOL (DMIG-form) block is not read from an OP2: one sentence, what to do."""
    op2 = nas.modes.load_op2(se_op2)
    op2.matrices["KAA"].is_matpool = True
    with pytest.raises(nas.NastranError, match="DMIG \\(MATPOOL\\) form.*PARAM,EXTOUT,DMIGPCH"):
        nas.matrices.op2_matrices(op2, se_op2)


def test_symmetric_check_tolerates_float32_rounding():
    """One float32 rounding of an entry (1.2e-7 of it) is below the threshold."""
    A = sp.csc_matrix(np.array([[2.0, 1.0], [1.0 + 1.2e-7, 3.0]]))
    K = nas.matrices.to_si(A, [(1, 1), (1, 2)], "SI", "stiffness matrix K", "x.op2")
    assert K.shape == (2, 2)
