"""NASTRAN import on real NASTRAN output (../shared/nastran, see its README), used in place.

References are read from the files by the tests themselves, independently of the
importer: the F06 eigenvalue and eigenvector tables (text), the superelement's OP4 KAA
and MAA parsed here from their ASCII text in double precision, Euler-Bernoulli beam
theory for the cantilever's static deflection.
"""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as la

from structfmu import nastran as nas
from tests.support.nastran_data import nastran_data
from structfmu.statespace import frf

SHARED = nastran_data()
BEAM = SHARED / "beam_modes"
SDOF = SHARED / "sdof_crod"
SE = SHARED / "superelement_n11"
pytestmark = pytest.mark.skipif(not SHARED.is_dir(), reason=f"real NASTRAN files not at {SHARED}: set "
                                "JITTERFMU_NASTRAN_DATA to the shared/nastran folder")


def f06_eigenvalues(path):
    """MODE, EIGENVALUE, CYCLES, GENERALIZED MASS of the F06's REAL EIGENVALUES table."""
    rows, on = [], False
    for line in Path(path).read_text().splitlines():
        if "R E A L   E I G E N V A L U E S" in line:
            on = True
            continue
        if on:
            parts = line.split()
            if len(parts) == 7 and parts[0].isdigit():
                rows.append([float(x) for x in parts])
            elif rows:
                break
    return np.array(rows)


def f06_eigenvectors(path):
    """``{mode: {grid: (T1..R3)}}`` from the F06's REAL EIGENVECTOR tables."""
    out, mode = {}, None
    for line in Path(path).read_text().splitlines():
        m = re.search(r"R E A L   E I G E N V E C T O R   N O \.\s+(\d+)", line)
        if m:
            mode = int(m.group(1))
            out.setdefault(mode, {})
            continue
        parts = line.split()
        if mode is not None and len(parts) == 8 and parts[1] == "G":
            out[mode][int(parts[0])] = np.array([float(x) for x in parts[2:]])
    return out


def op4_ascii(path, name):
    """A real ASCII OP4 matrix (dense or sparse string records), parsed as float64 here.

    Each column: ``col, row, nw``; ``row > 0`` dense (``nw`` values from ``row``), ``row
    == 0`` sparse: ``nw`` words of string headers ``IS = 65536 (L + 1) + irow`` each
    followed by ``L`` values from ``irow``.
    """
    lines = Path(path).read_text().splitlines()
    k = next(i for i, ln in enumerate(lines)
             if re.match(rf"\s*\d+\s+\d+\s+\d+\s+\d+{name}\s", ln))
    ncol, nrow = (int(x) for x in lines[k].split()[:2])
    A = np.zeros((nrow, ncol))
    num = re.compile(r"[-+]?\d\.\d+E[-+]\d+")
    i = k + 1

    def values(count):
        nonlocal i
        vals = []
        while len(vals) < count:
            vals += [float(x) for x in num.findall(lines[i])]
            i += 1
        return vals

    while True:
        col, row, nw = (int(x) for x in lines[i].split()[:3])
        i += 1
        if col > ncol:
            return A
        if row > 0:
            A[row - 1:row - 1 + nw, col - 1] = values(nw)
            continue
        left = nw
        while left > 0:
            head = int(lines[i].split()[0])
            i += 1
            count, irow = head // 65536 - 1, head % 65536
            A[irow - 1:irow - 1 + count, col - 1] = values(count)
            left -= count + 1


def quiet_import(*args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", nas.NastranWarning)
        return nas.import_nastran(*args, **kw)


# -- beam_modes: SOL 103 cantilever, OP2 (MSC 2013) and F06 (Simcenter 2021) --------------

def test_beam_frequencies_match_the_f06_table(capfd):
    table = f06_eigenvalues(BEAM / "beam_modes.f06")
    assert table.shape == (10, 7)
    with pytest.warns(nas.NastranWarning, match="modes only") as record:
        model = nas.import_nastran(BEAM / "beam_modes.dat", units="in-lbf-s",
                                   op2=BEAM / "beam_modes_m1.op2", n_modes=10,
                                   sensors=[nas.parse_point("tip=11:3")])
    # the deck is complete and every card is interpreted: no other warning
    assert all("modes only" in str(w.message) for w in record)
    # F06 prints 7 digits (half a unit in the last: 1.1e-7 relative at worst), and the
    # OP2 (float32 eigenvalues, 6e-8) is of an earlier run: the 1e-6
    np.testing.assert_allclose(model.frequencies_hz, table[:, 4], rtol=1e-6)
    captured = capfd.readouterr()
    assert captured.out == "" and captured.err == ""  # pyNastran's log kept quiet


def test_beam_mode_shapes_match_the_f06_vectors():
    """Unrepeated modes 5 (axial) and 6 (torsion) and the bending pairs as subspaces."""
    vec = f06_eigenvectors(BEAM / "beam_modes.f06")
    grids = range(2, 12)
    sensors = [nas.parse_point(f"g{g}c{c}=%d:%d" % (g, c)) for g in grids for c in range(1, 7)]
    model = quiet_import(BEAM / "beam_modes.dat", units="in-lbf-s",
                         op2=BEAM / "beam_modes_m1.op2", n_modes=10, sensors=sensors)
    length = np.array([0.0254 if c <= 3 else 1.0 for g in grids for c in range(1, 7)])
    shapes = model.C_e / length[:, None]  # back to the file's units (in, rad)
    ref = np.array([np.concatenate([vec[m][g] for g in grids]) for m in range(1, 11)]).T
    for m in (4, 5):  # 0-based: modes 5 and 6
        a, b = shapes[:, m], ref[:, m]
        a = a * (b @ b) / (a @ b)  # normalise (MAX here, mass there) and sign
        # F06 prints 7 digits: 1e-6 of the largest component
        np.testing.assert_allclose(a, b, atol=1e-6 * np.abs(b).max())
    for pair in ((0, 1), (2, 3), (6, 7), (8, 9)):  # repeated roots: any basis of the plane
        Q, _ = np.linalg.qr(shapes[:, pair])
        R = ref[:, pair]
        resid = R - Q @ (Q.T @ R)
        assert np.abs(resid).max() < 1e-5 * np.abs(R).max()


def test_beam_static_deflection_against_beam_theory():
    """Tip load on the PBARL ROD cantilever (E = 3e7, G = 1.1628e7, r = 1, L = 10, in-lbf-s).

    NASTRAN gives a PBARL section its shear flexibility, so the reference is Timoshenko:
    ``delta = F L^3 / (3 E I) + F L / (kappa G A)``, ``I = pi r^4 / 4``, with the solid
    circle's ``kappa = 6 (1 + nu) / (7 + 6 nu)`` (Cowper).  The shear term is 2.2 % of
    the total; ``kappa`` between Cowper and 0.9 moves it by 0.05 %.  The ten OP2 modes hold
    the static compliance less the omitted higher modes (which only add, < 0.3 % here),
    and Euler-Bernoulli alone is off by 2 %: the test tells the two apart.
    """
    model = quiet_import(BEAM / "beam_modes.dat", units="in-lbf-s",
                         op2=BEAM / "beam_modes_m1.op2", n_modes=10,
                         loads=[nas.parse_point("fz=11:3", "force")],
                         sensors=[nas.parse_point("uz=11:3")])
    from fmukit.units import INCH, LBF

    E, G, r, L = 3.0e7, 1.1628e7, 1.0, 10.0
    nu = E / (2 * G) - 1
    kappa = 6 * (1 + nu) / (7 + 6 * nu)
    bending = L**3 / (3 * E * np.pi * r**4 / 4)  # in per lbf
    shear = L / (kappa * G * np.pi * r**2)
    g = frf(model, [1e-3], ["uz"], ["fz"])[0, 0, 0].real / (INCH / LBF)  # far below 456 Hz
    assert 0.997 < g / (bending + shear) < 1.0005, g / (bending + shear)
    assert g / bending > 1.015  # Euler-Bernoulli alone misses the shear term


def test_sdof_crod_frequency():
    """One CROD (EA/L = 1e4) and a CONM2 of 100: sqrt(100)/(2 pi) = 1.5915494 Hz."""
    with pytest.warns(nas.NastranWarning) as record:
        model = nas.import_nastran(SDOF / "sdof_crod.bdf", units="SI",
                                   op2=SDOF / "sdof_crod_2014.op2", n_modes=1)
    # this OP2 has no LAMA: the generalized mass of 1 is an assumption, and it says so
    assert any("no eigenvalue table (LAMA)" in str(w.message) for w in record)
    np.testing.assert_allclose(model.frequencies_hz, [np.sqrt(1e4 / 100) / (2 * np.pi)],
                               rtol=1e-6)


# -- superelement_n11: MSC external superelement (Craig-Bampton), KAA/MAA in OP4 --------

@pytest.fixture(scope="module")
def se_matrices():
    return op4_ascii(SE / "se_test_n11.op4", "KAA"), op4_ascii(SE / "se_test_n11.op4", "MAA")


def test_superelement_fixed_interface_modes(se_matrices):
    K, M = se_matrices
    q = slice(66, 105)  # the 39 SPOINTs after the 11 boundary grids x 6
    ref = np.sqrt(la.eigh(K[q, q], M[q, q], eigvals_only=True)) / (2 * np.pi)
    model = quiet_import(SE / "se_test_n11.pch", units="SI", op4=SE / "se_test_n11.op4",
                         n_modes=39, boundary="fixed", ritz="none",
                         sensors=[nas.parse_point("q1=20111101:0")])
    # the q-set of 39 DOF in double precision: eps * cond ~ 1e-13; the 1e-9
    np.testing.assert_allclose(model.frequencies_hz, ref, rtol=1e-9)
    np.testing.assert_allclose(ref[:3], [365.260, 370.233, 381.422], rtol=2e-6)  # README


def test_superelement_free_free_rigid_body_modes(se_matrices):
    """The boundary free: six rigid-body modes, as the double-precision digits give."""
    K, M = se_matrices
    dofs = nas.gset(nas.read_deck(SE / "se_test_n11.pch", "SI"))
    assert len(dofs) == 105
    Ks, Ms = nas.read_matrices(SE / "se_test_n11.op4", dofs, "SI")
    np.testing.assert_allclose(Ks.toarray(), K, rtol=0, atol=1e-15 * np.abs(K).max())
    live = np.flatnonzero(np.abs(K).sum(0) + np.abs(M).sum(0) > 0)  # drop empty rotations
    lam = la.eigh(Ks.toarray()[np.ix_(live, live)], Ms.toarray()[np.ix_(live, live)],
                  eigvals_only=True)
    assert np.all(np.abs(lam[:6]) < 1e-6 * lam[6]), lam[:7]
    # read as the header's single precision, the same matrices give -0.455 (rad/s)^2
    OP4 = nas.pynastran()[2]
    single = OP4(log=nas.pyn.QuietLog().log).read_op4(str(SE / "se_test_n11.op4"),
                                                       precision="single")
    K1, M1 = (single[n].data for n in ("KAA", "MAA"))
    K1, M1 = (x.toarray() if hasattr(x, "toarray") else np.asarray(x) for x in (K1, M1))
    lam1 = la.eigh(np.float64(K1)[np.ix_(live, live)], np.float64(M1)[np.ix_(live, live)],
                   eigvals_only=True)
    assert lam1[0] < -0.1
    model = quiet_import(SE / "se_test_n11.pch", units="SI", op4=SE / "se_test_n11.op4",
                         n_modes=12, shift=-1e3, boundary="free",
                         loads=[nas.parse_point("fx=20110010:1", "force")],
                         sensors=[nas.parse_point("ux=20110038:1:accel")])
    assert np.sum(model.omega == 0) == 6
    np.testing.assert_allclose(model.omega[6:] ** 2, lam[6:12], rtol=1e-9)
    assert model.n_ritz == 1  # the static Ritz vector of the interface load


# -- never a misread model without a word ------------------------------------------------

def test_unread_cards_and_missing_enddata_are_warned(tmp_path):
    text = (BEAM / "beam_modes.dat").read_text()
    extra = ("CELAS1  100     101     2       3       3       3\n"
             "PELAS   101     1.0e3\n"
             "CELAS1  102     101     4       3       5       3\n"
             "CFAKE   7       1       2\n")
    (tmp_path / "cbar_cbeam.blk").write_text((BEAM / "cbar_cbeam.blk").read_text())
    deck = tmp_path / "extra.dat"
    deck.write_text(text.replace("ENDDATA", extra + "ENDDATA"))
    with pytest.warns(nas.NastranWarning) as record:
        nas.read_deck(deck, "in-lbf-s")
    msgs = [str(w.message) for w in record]
    assert len(msgs) == 1
    assert re.search(r"4 cards this import does not interpret: CELAS1 \(2\), CFAKE \(1, "
                     r"unknown to pyNastran\), PELAS \(1\)", msgs[0]), msgs[0]
    cut = tmp_path / "cut.dat"
    cut.write_text(text[:text.index("$*  RESTRAINT CARDS")])
    with pytest.warns(nas.NastranWarning, match="has no ENDDATA: it may be cut short"):
        d = nas.read_deck(cut, "in-lbf-s")
    assert not d.constrained  # the SPC was indeed cut


def test_pynastran_reason_is_in_the_one_sentence_error(tmp_path, capfd):
    bad = tmp_path / "bad.bdf"
    bad.write_text("CEND\nBEGIN BULK\nGRID,1,,0.,0.,0.\nGRID,2,,1.,0.,0.\n"
                   "CBAR,1,1,1,2,0.,1.,0.\nMAT1,1,3e7,,0.3\nENDDATA\n")
    with pytest.raises(nas.NastranError) as exc:
        nas.read_deck(bad, "SI")
    msg = str(exc.value)
    assert "pid=1 not found, which is required by CBAR eid=1" in msg
    assert "\n" not in msg and "cross-reference errors" not in msg
    out = capfd.readouterr()
    assert out.out == "" and out.err == ""  # pyNastran's log kept quiet


def test_op2_of_another_model_is_an_error():
    with pytest.raises(nas.NastranError, match="the OP2 is of another model"):
        quiet_import(BEAM / "beam_modes.dat", units="in-lbf-s",
                     op2=SDOF / "sdof_crod_2014.op2", n_modes=1)
    with pytest.raises(nas.NastranError, match="not in .*sdof_crod.bdf.*another model"):
        quiet_import(SDOF / "sdof_crod.bdf", units="SI", op2=BEAM / "beam_modes_m1.op2",
                     n_modes=1)


def test_op2_of_a_moved_grid_is_an_error(tmp_path):
    """Same ids, another geometry: the OP2's grid table (BGPDT) disagrees with the BDF."""
    (tmp_path / "cbar_cbeam.blk").write_text((BEAM / "cbar_cbeam.blk").read_text().replace(
        "GRID           6       0 5.00000", "GRID           6       0 5.10000"))
    (tmp_path / "moved.dat").write_text((BEAM / "beam_modes.dat").read_text())
    with pytest.raises(nas.NastranError, match=r"grid 6 is at \[5\.0, 0\.0, 0\.0\] in OP2 .* but "
                                               r"at \[5\.1, 0\.0, 0\.0\] in .*another model"):
        quiet_import(tmp_path / "moved.dat", units="in-lbf-s", op2=BEAM / "beam_modes_m1.op2",
                     n_modes=4)


def test_op4_of_another_model_is_an_error():
    with pytest.raises(nas.NastranError, match=r"have 105 rows, but .*beam_modes.dat has a "
                                               r"g-set of 72 DOFs.*different models"):
        quiet_import(BEAM / "beam_modes.dat", units="in-lbf-s", op4=SE / "se_test_n11.op4",
                     n_modes=4)


def test_wtmass_scales_the_member_mass(tmp_path):
    """PARAM,WTMASS multiplies the BDF's masses (here a CBAR's rho A L), as NASTRAN does."""
    text = (BEAM / "beam_modes.dat").read_text()
    (tmp_path / "cbar_cbeam.blk").write_text((BEAM / "cbar_cbeam.blk").read_text()
                                             .replace("7.4851-4", "0.28899"))  # rho in lbm/in^3
    deck = tmp_path / "wt.dat"
    deck.write_text(text.replace("PARAM   AUTOSPC YES", "PARAM   AUTOSPC YES\n"
                                 "PARAM   WTMASS  .0025901"))
    plain = nas.read_deck(BEAM / "beam_modes.dat", "in-lbf-s")
    scaled = nas.read_deck(deck, "in-lbf-s")
    assert scaled.wtmass == 0.0025901
    np.testing.assert_allclose(scaled.elements[1][3], plain.elements[1][3] * 0.28899 * 0.0025901
                               / 7.4851e-4, rtol=1e-12)
    assert abs(scaled.elements[1][3] / plain.elements[1][3] - 1) < 1e-3  # 0.28899 lbm = 7.4851e-4


#: A git clone (or bare mirror) of the public pyNastran repository, for its SOL 145 OP2.
FLUTTER = os.environ.get("JITTERFMU_PYNASTRAN_REPO", "")


def test_sol145_op2_says_what_to_rerun(tmp_path):
    """A real SOL 145 OP2 (pyNastran's models/aero/2_mode_flutter, MSC) when available."""
    import subprocess

    op2 = tmp_path / "flutter.op2"
    try:
        if not FLUTTER:
            raise OSError
        blob = subprocess.run(["git", "-C", FLUTTER, "show",
                               "HEAD:models/aero/2_mode_flutter/0012_flutter.op2"],
                              capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("no SOL 145 OP2 here: set JITTERFMU_PYNASTRAN_REPO to a clone of the "
                    "pyNastran repository (its models/aero/2_mode_flutter)")
    op2.write_bytes(blob)
    with pytest.raises(nas.NastranError, match=r"complex eigenvalues or responses .* SOL 145 "
                                               r"flutter.* rerun the bulk data as "
                                               r"SOL 103 .*DISP\(PLOT\)=ALL"):
        nas.read_modes(op2, "in-lbf-s", 2)


@pytest.mark.slow
def test_beam_structure_fmu_static_deflection(tmp_path):
    """The imported cantilever as a structure FMU in FMPy: a constant tip force settles
    to the Timoshenko deflection (as the model's own static gain above).

    Damping 70 % of critical on every mode so that the response settles within the run
    (first mode 456 Hz: time constant 0.5 ms; 50 ms is 100 of them, e^-100 left).
    """
    import fmpy

    from fmukit.units import INCH, LBF
    from structfmu.fmuspec import build_structure_fmu
    from structfmu.reduce import Damping

    model = quiet_import(BEAM / "beam_modes.dat", units="in-lbf-s",
                         op2=BEAM / "beam_modes_m1.op2", n_modes=10,
                         loads=[nas.parse_point("fz=11:3", "force")],
                         sensors=[nas.parse_point("uz=11:3")], damping=Damping(zeta=0.7))
    npz = model.save(tmp_path / "beam.npz")
    report = build_structure_fmu(npz, tmp_path / "fmus")
    assert not report.problems, report.problems
    force = 100.0  # N
    signal = np.array([(0.0, force), (1.0, force)], dtype=[("time", float), ("fz", float)])
    res = fmpy.simulate_fmu(str(report.fmus[0]), stop_time=0.05, output_interval=1e-4,
                            input=signal, output=["uz"])
    E, G, r, L = 3.0e7, 1.1628e7, 1.0, 10.0
    nu = E / (2 * G) - 1
    kappa = 6 * (1 + nu) / (7 + 6 * nu)
    delta = (L**3 / (3 * E * np.pi * r**4 / 4) + L / (kappa * G * np.pi * r**2)) * INCH / LBF
    dc = frf(model, [0.0], ["uz"], ["fz"])[0, 0, 0].real
    np.testing.assert_allclose(res["uz"][-1], force * dc, rtol=1e-9)
    assert 0.997 < res["uz"][-1] / (force * delta) < 1.0005


def test_cli_imports_the_superelement_with_its_boundary_fixed(tmp_path, capfd):
    """``import-nastran se.pch --op4 se.op4 --boundary fixed``: 39 fixed-interface modes,
    nothing printed but the start line and the summary (the punch file needs no ENDDATA,
    EXTRN is read)."""
    from orchestrator.cli import main
    from orchestrator.cli._options import shown
    from structfmu.reduced import ReducedModel

    out = tmp_path / "se.npz"
    rc = main(["import-nastran", str(SE / "se_test_n11.pch"), "--op4", str(SE / "se_test_n11.op4"),
               "--units", "SI", "--modes", "39", "--boundary", "fixed", "--ritz", "none",
               "--sensor", "q1=20111101:0", "--out", str(out)])
    assert rc == 0
    captured = capfd.readouterr()
    assert captured.err.splitlines() == [
        f"jitterfmu: import-nastran {shown(SE / 'se_test_n11.pch')}: reading the deck and the "
        "OP4 file, reducing to 39 modes"] and captured.out.count("\n") == 1
    assert "39 modes (365.3-1976 Hz)" in captured.out
    assert ReducedModel.load(out).meta["boundary"] == "fixed"
    # fixed boundary and a load on it: one sentence
    rc = main(["import-nastran", str(SE / "se_test_n11.pch"), "--op4", str(SE / "se_test_n11.op4"),
               "--units", "SI", "--modes", "4", "--boundary", "fixed",
               "--load", "f=20110010:1", "--out", str(tmp_path / "x.npz")])
    assert rc == 2
    assert "load 'f': every DOF it uses is constrained" in capfd.readouterr().err
