"""FMU specifications of the structure FMUs (one per built-in model, or from a .npz)."""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

from fmutools.build import BuildReport, FmuSpec, build_fmu
from fmutools.validate import validate_fmu
from structfmu.models import _registry, get_model
from structfmu.reduced import ReducedModel

MODELS = ("truss10", "eos_testbed")


def spec_from_model(model: ReducedModel, model_identifier: str, description: str = "") -> FmuSpec:
    """An FMU spec packaging a reduced model (written as the ``model.npz`` resource).

    Parameters
    ----------
    model : ReducedModel
        The model the FMU steps.
    model_identifier : str
        FMI modelIdentifier of the FMU.
    description : str
        FMU description; default names the model and its numbers of modes and Ritz
        vectors.

    Returns
    -------
    FmuSpec
        Spec for :class:`structfmu.slave.StructureSlave` with the model as a resource.
    """
    with tempfile.TemporaryDirectory() as tmp:
        path = model.save(Path(tmp) / "model.npz")
        data = path.read_bytes()
    return FmuSpec(model_identifier=model_identifier,
                   slave_class="structfmu.slave:StructureSlave",
                   resources={"model.npz": data},
                   description=description or f"reduced structure {model.name}: "
                   f"{model.n_modes} modes + {model.n_ritz} Ritz vectors")


def spec_from_npz(path, model_identifier: str) -> FmuSpec:
    """An FMU spec for a reduced model saved with :meth:`ReducedModel.save`.

    Parameters
    ----------
    path : path-like
        The ``.npz`` file.
    model_identifier : str
        FMI modelIdentifier of the FMU.

    Returns
    -------
    FmuSpec
        As :func:`spec_from_model`, with the default description.
    """
    return spec_from_model(ReducedModel.load(path), model_identifier)


def build_structure_fmu(npz, out_dir, model_identifier: str | None = None):
    """Build and validate a structure FMU from a reduced model file.

    Parameters
    ----------
    npz : path-like
        A file written by :meth:`ReducedModel.save` (e.g. by ``jitterfmu import-nastran``).
    out_dir : path-like
        Destination folder.
    model_identifier : str, optional
        FMI modelIdentifier and file stem; default ``<npz stem>_structure``.

    Returns
    -------
    fmutools.build.BuildReport
        The FMU path and its validation problems (one line each).
    """
    npz = Path(npz)
    ident = model_identifier or re.sub(r"\W", "_", npz.stem) + "_structure"
    if ident[0].isdigit():
        ident = "m" + ident
    path = build_fmu(spec_from_npz(npz, ident), out_dir)
    return BuildReport((path,), tuple(validate_fmu(path, strict=True)))


def specs(models=None) -> list[FmuSpec]:
    """Specs of the structure FMUs of the built-in models (``<model>_structure``)."""
    names = [m for m in MODELS if m in _registry()]
    if models:
        names = [m.removesuffix("_structure") for m in models
                 if m.removesuffix("_structure") in names]
    out = []
    for name in names:
        mod = get_model(name)
        out.append(spec_from_model(mod.reduced(), f"{name}_structure"))
    return out
