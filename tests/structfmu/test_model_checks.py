"""A reduced model that is not a physical structure is refused wherever it enters: built
in memory, loaded from a file, or handed to either build (Python or native)."""

import dataclasses

import numpy as np
import pytest

from orchestrator.cli import main
from structfmu.errors import ModelError
from structfmu.reduced import ReducedModel


@pytest.fixture(scope="module")
def model(truss10_reduced):
    """The ten-bay truss reduced to 6 modes + 2 Ritz vectors."""
    return truss10_reduced[0]


def raw_npz(model, path, **arrays):
    """Write ``model`` as a .npz with some arrays replaced, bypassing the checks (the way
    a file from another tool, or an edited one, arrives)."""
    model.save(path)
    with np.load(path, allow_pickle=False) as f:
        data = {k: f[k] for k in f.files}
    data.update(arrays)
    np.savez(path, **data)
    return path


def test_negative_modal_damping_is_refused(model):
    with pytest.raises(ModelError, match=r"mode 1 has modal_damping -0.4776[0-9]+; a negative "
                       r"damping \(it would feed energy in\) makes an unstable structure"):
        c = model.modal_damping.copy()
        c[1] = -abs(c[1])
        dataclasses.replace(model, modal_damping=c)
    with pytest.raises(ModelError, match="negative damping"):
        model.with_modal_damping(-0.01)


def test_non_finite_entries_are_refused(model):
    C = model.C_e.copy()
    C[2, 3] = np.nan
    with pytest.raises(ModelError, match=r"C_e has a non-finite entry \(nan at index "
                       r"\(2, 3\)\); every matrix entry must be a finite number"):
        dataclasses.replace(model, C_e=C)
    w = model.omega.copy()
    w[0] = np.inf
    with pytest.raises(ModelError, match=r"omega has a non-finite entry \(inf at index \(0,\)\)"):
        dataclasses.replace(model, omega=w)


def test_an_indefinite_ritz_block_is_refused(model):
    assert model.n_ritz > 0
    D = model.D_oo.copy()
    D[0, 0] = -1.0
    with pytest.raises(ModelError, match=r"Ritz-block damping D_oo has an eigenvalue "
                       r"-?[0-9.e+-]+ < 0; a damping matrix must be positive semi-definite"):
        dataclasses.replace(model, D_oo=D)


def test_a_physical_model_passes(model):
    # rigid-body modes (omega = 0, no damping) and the shipped model are physical
    m = dataclasses.replace(model, omega=np.r_[0.0, model.omega[1:]],
                            modal_damping=np.r_[0.0, model.modal_damping[1:]])
    assert m.omega[0] == 0.0


@pytest.mark.parametrize("flavour", ["--python", "--native"])
@pytest.mark.parametrize("fault", ["negative-damping", "nan"])
def test_both_builds_refuse_a_bad_model_file(model, tmp_path, capsys, flavour,
                                              fault):
    if fault == "nan":
        C = model.C_e.copy()
        C[0, 0] = np.nan
        arrays = {"C_e": C}
    else:
        arrays = {"modal_damping": -model.modal_damping}
    npz = raw_npz(model, tmp_path / "bad.npz", **arrays)
    with pytest.raises(ModelError):
        ReducedModel.load(npz)
    code = main(["build", flavour, "--structure", str(npz), "--out", str(tmp_path / "f")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith(f"jitterfmu: error: {str(npz)!r}: reduced model ")
    assert ("must be a finite number" if fault == "nan" else "negative damping") in err
    assert not list((tmp_path / "f").rglob("*.fmu"))
