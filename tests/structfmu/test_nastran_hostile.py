"""NASTRAN files a hostile or careless user hands the importer.

A NaN or inf in an OP4 or DMIG matrix used to give other frequencies without a word;
a BDF ``INCLUDE '/etc/passwd'`` (or ``'../../x'``) was read and its lines echoed as
card names in the unread-cards warning; a DMIG without mass was called an "OP4";
``--zeta -0.1`` passed.  Each is now one sentence naming the file and the entry, and
an INCLUDE is followed only inside the deck's folder or a folder the user names.
"""

from __future__ import annotations

import os
import re
import warnings

import numpy as np
import pytest

from orchestrator.cli import main
from structfmu import nastran as nas
from structfmu.reduce import Damping

from .test_nastran_rigid import write_dmig, write_model

SECRET = "zzsecretzz:x:0:0:hidden:/home:/bin/sh"


def _write_op4(path, K, M):
    OP4 = nas.pynastran()[2]
    OP4(log=nas.pyn.QuietLog().log).write_op4(str(path), {"KGG": (6, K), "MGG": (6, M)},
                                              is_binary=False)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_non_finite_op4_entry_is_named_by_matrix_row_and_column(tmp_path, bad):
    bdf, op4, K, M = write_model(tmp_path, rigid=False)
    K = K.copy()
    K[3, 3] = bad
    _write_op4(op4, K, M)
    with pytest.raises(nas.NastranError, match=r"stiffness matrix KGG in '.*rigid.op4' holds "
                       r"-?(nan|inf) at row 4, column 4 \(non-finite entries: 1\)"):
        nas.import_nastran(bdf, units="SI", op4=op4, n_modes=4, ritz="none")


def test_the_same_op4_without_the_nan_imports(tmp_path):
    """The refusal is the NaN's: the file written the same way with finite values reads."""
    bdf, op4, K, M = write_model(tmp_path, rigid=False)
    _write_op4(op4, K, M)
    model = nas.import_nastran(bdf, units="SI", op4=op4, n_modes=4, ritz="none")
    assert np.all(np.isfinite(model.omega)) and model.n_modes == 4


def _write_dmig(tmp_path, K, M, names=("KAAX", "MAAX")):
    return write_dmig(tmp_path / "m.pch", K, M, names)


def test_a_nan_in_a_dmig_is_named(tmp_path):
    bdf, _, K, M = write_model(tmp_path, rigid=False)
    pch = _write_dmig(tmp_path, K, M)
    # the first value of KAAX's column of grid 2 component 1, written as text
    text, n = re.subn(r"(DMIG\*\s+KAAX\s+2\s+1\n\*\s+2\s+)(\S+)",
                      lambda m: m.group(1) + f"{'NaN':>{len(m.group(2))}}", pch.read_text(),
                      count=1)
    assert n == 1
    pch.write_text(text)
    with pytest.raises(nas.NastranError, match=r"DMIG KAAX in '.*m.pch' holds nan at row \d+, "
                                               r"column \d+"):
        nas.import_nastran(bdf, units="SI", dmig=pch, n_modes=4, ritz="none")


def test_a_dmig_file_without_mass_is_called_a_dmig_file(tmp_path):
    bdf, _, K, M = write_model(tmp_path, rigid=False)
    pch = _write_dmig(tmp_path, K, K, names=("KAAX", "BAAX"))
    with pytest.raises(nas.NastranError, match=r"^DMIG file '.*m.pch' has matrices BAAX, KAAX, none a "
                                               r"square mass matrix named M"):
        nas.import_nastran(bdf, units="SI", dmig=pch, n_modes=4, ritz="none")


@pytest.mark.parametrize("zeta, ritz", [(-0.1, 0.02), (5.0, 0.02), (0.01, 1.0)])
def test_a_damping_ratio_outside_0_1_is_refused(tmp_path, zeta, ritz):
    bdf, op4, _, _ = write_model(tmp_path, rigid=False)
    with pytest.raises(nas.NastranError, match=r"damping ratio zeta(_ritz)? = .*expected "
                                               r"0 <= zeta < 1"):
        nas.import_nastran(bdf, units="SI", op4=op4, n_modes=4, ritz="none",
                           damping=Damping(zeta=zeta, zeta_ritz=ritz))


# ----------------------------------------------------------------------------- INCLUDE


@pytest.fixture()
def outside(tmp_path):
    """A deck in deck/ and a file of secret lines beside that folder."""
    (tmp_path / "deck").mkdir()
    secret = tmp_path / "secret.txt"
    secret.write_text(f"{SECRET}\nSECRET2,3,4\n")
    bdf, op4, _, _ = write_model(tmp_path / "deck", rigid=False)
    return bdf, op4, secret


def _with_include(bdf, name):
    text = bdf.read_text().replace("ENDDATA", f"INCLUDE '{name}'\nENDDATA")
    bdf.write_text(text)


@pytest.mark.parametrize("how", ["absolute", "dotdot", "link"])
def test_an_include_outside_the_decks_folder_is_refused_without_its_lines(outside, how):
    bdf, op4, secret = outside
    if how == "link":
        os.symlink(secret, bdf.parent / "inside.txt")
    name = {"absolute": str(secret), "dotdot": "../secret.txt", "link": "inside.txt"}[how]
    _with_include(bdf, name)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(nas.NastranError, match=r"has INCLUDE .* a file outside the folder "
                                                   r".*--include-dir") as info:
            nas.import_nastran(bdf, units="SI", op4=op4, n_modes=4, ritz="none")
    said = str(info.value) + "".join(str(w.message) for w in caught)
    assert "ZZSECRETZZ" not in said.upper() and "SECRET2" not in said.upper()


def test_an_include_in_an_allowed_folder_is_read_and_its_lines_never_echoed(outside, capsys):
    bdf, op4, secret = outside
    _with_include(bdf, str(secret))
    out = bdf.parent / "m.npz"
    argv = ["import-nastran", str(bdf), "--op4", str(op4), "--units", "SI", "--modes", "4",
            "--ritz", "none", "--out", str(out)]
    assert main(argv) == 2
    assert "a file outside the folder" in capsys.readouterr().err
    assert main([*argv, "--include-dir", str(secret.parent)]) == 0
    said = capsys.readouterr()
    assert out.exists()
    assert "ZZSECRETZZ" not in (said.err + said.out).upper()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        nas.read_deck(bdf, "SI", include_dirs=[secret.parent])
    text = " ".join(str(w.message) for w in caught)
    assert "2 lines that are not NASTRAN cards" in text and "ZZSECRETZZ" not in text.upper()


def test_an_include_inside_the_decks_folder_is_read(outside):
    bdf, op4, _ = outside
    grid = bdf.parent / "extra.bdf"
    grid.write_text("GRID    99              0.0     0.0     0.0\n")
    _with_include(bdf, "extra.bdf")
    deck = nas.read_deck(bdf, "SI")
    assert 99 in deck.grids


# ----------------------------------------------------------------------------- files


@pytest.mark.parametrize("content, message", [
    (b"", r"OP4 '.*x.op4' holds no matrix \(0 bytes\)"),
    (bytes(range(256)) * 12, r"cannot read OP4 '.*x.op4': .*check that it is an OUTPUT4"),
])
def test_an_empty_or_garbage_op4_is_one_sentence_and_nothing_printed(tmp_path, capfd, content,
                                                                      message):
    """pyNastran printed its own dump ("doubles(d) = ...") of a garbage OP4 to the
    console before the error; now the error is the only word."""
    bdf, _, _, _ = write_model(tmp_path, rigid=False)
    op4 = tmp_path / "x.op4"
    op4.write_bytes(content)
    capfd.readouterr()
    with pytest.raises(nas.NastranError, match=message):
        nas.import_nastran(bdf, units="SI", op4=op4, n_modes=4, ritz="none")
    out = capfd.readouterr()
    assert out.out == "" and out.err == ""


def test_a_fixed_boundary_on_the_modes_of_an_op2_is_refused(tmp_path):
    """--boundary fixed was ignored without a word when the modes came from an OP2."""
    from structfmu.models import truss10

    truss = truss10.build()
    n = len(truss.nodes)
    bdf, _ = nas.write_truss_deck(truss, tmp_path / "t.bdf", tmp_path / "t.op4")
    phi = np.zeros((6 * n, 2))
    phi[0, 0] = phi[1, 1] = 1.0
    op2 = nas.write_modes_op2(tmp_path / "m.op2", np.array([100.0, 200.0]), phi,
                              np.arange(1, n + 1))
    with pytest.raises(nas.NastranError, match=r"boundary='fixed' builds the fixed-interface "
                                               r"modes .* leave --boundary out"):
        nas.import_nastran(bdf, units="SI", op2=op2, n_modes=2, ritz="none",
                           boundary="fixed")


def test_a_repeated_grid_id_is_named_as_such(tmp_path):
    """pyNastran's reason was "nid=1"; now the card, the id and what to do."""
    bdf, op4, _, _ = write_model(tmp_path, rigid=False)
    bdf.write_text(bdf.read_text().replace(
        "ENDDATA", "GRID           1              5.      0.      0.\nENDDATA"))
    with pytest.raises(nas.NastranError, match=r"cannot read BDF '.*rigid.bdf': two GRID cards "
                                               r"have the id 1 \(nid\); give each its own id"):
        nas.import_nastran(bdf, units="SI", op4=op4, n_modes=4, ritz="none")


def test_the_unread_cards_warning_is_shown_when_the_import_then_fails(tmp_path, capsys):
    bdf, op4, K, M = write_model(tmp_path, rigid=False)
    bdf.write_text(bdf.read_text().replace("ENDDATA", "CFAKE   7       1       2\nENDDATA"))
    K = K.copy()
    K[3, 3] = np.nan
    _write_op4(op4, K, M)
    code = main(["import-nastran", str(bdf), "--op4", str(op4), "--units", "SI", "--modes",
                 "4", "--ritz", "none", "--out", str(tmp_path / "m.npz")])
    err = capsys.readouterr().err
    assert code == 2
    assert "cards this import does not interpret: CFAKE (1, unknown to pyNastran)" in err
    assert "holds nan at row 4, column 4" in err


def _op2_with(vectors, eigenvalues=None):
    """An object shaped as pyNastran's OP2, holding tables of the given class names."""
    from types import SimpleNamespace

    def table(name, **attrs):
        return type(name, (), attrs)()
    return SimpleNamespace(
        eigenvectors={i: table(n, **a) for i, (n, a) in enumerate(vectors)},
        eigenvalues={i: table(n) for i, n in enumerate(eigenvalues or [])},
        op2_results=SimpleNamespace(vg_vf_response=None))


@pytest.mark.parametrize("op2, message", [
    (_op2_with([("RealEigenvectorArray", {"analysis_code": 7})]), r"holds buckling modes "
     r"\(SOL 105\), whose eigenvalues are load factors"),
    (_op2_with([("ComplexEigenvectorArray", {})], ["ComplexEigenvalues"]),
     r"holds complex eigenvalues or responses \(SOL 107/110 complex modes"),
])
def test_an_op2_of_buckling_or_complex_modes_is_named_for_what_it_is(op2, message):
    """SOL 105 failed with "'RealEigenvectorArray' object has no attribute 'eigns'"; SOL
    107 complex modes were called aeroelastic."""
    from structfmu.nastran.modes import _real_eigenvectors

    with pytest.raises(nas.NastranError, match=message + r".*rerun the bulk data as SOL 103"):
        _real_eigenvectors(op2, "m.op2")


def test_an_op4_holding_a_stack_of_matrices_is_named(tmp_path, monkeypatch):
    """A QHH (aerodynamic matrices per Mach number and frequency) read as one 3-D array
    failed with scipy's "CSR arrays don't yet support 3D"; pyNastran's reader stands in
    for such a file here (it returns what it read from a QHH OP4: a 3-D array)."""
    from types import SimpleNamespace

    bdf, op4, K, M = write_model(tmp_path, rigid=False)
    OP4 = nas.pynastran()[2]
    stack = np.zeros((3, 4, 4), complex)
    monkeypatch.setattr(OP4, "read_op4", lambda self, *a, **k: {
        "KGG": SimpleNamespace(data=K), "QHH": SimpleNamespace(data=stack)})
    with pytest.raises(nas.NastranError, match=r"holds QHH, an array of 3 dimensions "
                                               r"\(3, 4, 4\) .*not a stiffness or mass"):
        nas.import_nastran(bdf, units="SI", op4=op4, n_modes=4, ritz="none")


def test_a_removed_grid_still_named_by_a_card_is_one_line(tmp_path):
    """pyNastran's KeyError came through as its repr: the missing id and then every
    other grid id, across lines; now its first line only."""
    from structfmu.models import truss10

    bdf, op4 = nas.write_truss_deck(truss10.build(), tmp_path / "t.bdf", tmp_path / "t.op4")
    lines = bdf.read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("GRID*") and ln.split()[1] == "5")
    del lines[i:i + 2]                 # the large-field GRID 5 and its continuation
    bdf.write_text("\n".join(lines) + "\n")
    with pytest.raises(nas.NastranError) as info:
        nas.import_nastran(bdf, units="SI", op4=op4, n_modes=4, ritz="none")
    msg = str(info.value)
    assert "nids=[5] are not a GRID" in msg and "\\n" not in msg and "\n" not in msg
    assert " 46]" not in msg           # not the list of every other grid
