"""FMU specifications of the controller package: one FMU per control law.

Each named design of :data:`ctrlfmu.designs.DESIGNS` gives the FMU
``controller_<design>``, whose resource ``law.npz`` holds the discrete law and whose
DefaultExperiment step is the law's sample period.  :func:`law_spec` makes the same FMU
from any :class:`~ctrlfmu.law.DiscreteLaw`, e.g. a design retuned on a structure model.

Why one FMU per law rather than one FMU with a ``design`` String parameter: the
number of signals, their units (strain ``1`` vs ``m/s2``) and the exact
ModelStructure (a non-delayed law with ``D != 0`` has feedthrough, a delayed one none)
all depend on the law, and an FMU's modelDescription.xml cannot change with a
parameter; per-law FMUs keep each of them exact.
"""

from __future__ import annotations

import re
from pathlib import Path

from ctrlfmu.designs import DESIGNS, design
from ctrlfmu.law import DiscreteLaw, law_bytes, load_law
from fmutools.build import BuildReport, FmuSpec, build_fmu
from fmutools.validate import validate_fmu

__all__ = ["MODELS", "specs", "law_spec", "controller_identifier", "build_controller_fmu"]

PREFIX = "controller_"


def _design_names() -> list[str]:
    return sorted(DESIGNS)


#: modelIdentifier -> design name.
MODELS: dict[str, str] = {PREFIX + name: name for name in _design_names()}


def law_spec(law: DiscreteLaw, model_identifier: str | None = None) -> FmuSpec:
    """FMU specification of a controller FMU running ``law``.

    Parameters
    ----------
    law : DiscreteLaw
        The law; its outputs must share one pair of limits.
    model_identifier : str, optional
        Default ``"controller_" + law.name``.

    Returns
    -------
    FmuSpec
        Slave :class:`ctrlfmu.slave.ControllerSlave`, resource ``law.npz``,
        step size ``law.dt``.
    """
    form = "Eq. 11, one-sample delay" if law.delayed else "non-delayed"
    return FmuSpec(
        model_identifier=model_identifier or PREFIX + law.name,
        slave_class="ctrlfmu.slave:ControllerSlave",
        resources={"law.npz": law_bytes(law)},
        description=(f"Discrete controller {law.name} at {1 / law.dt:g} Hz ({form}): "
                     f"{law.description}"),
        step_size=law.dt,
    )


def specs(models: list[str] | None = None) -> list[FmuSpec]:
    """Return the specifications of the controller FMUs (named designs, default parameters).

    Parameters
    ----------
    models : list of str or None
        Model identifiers wanted; None for all of :data:`MODELS`.  Names this package
        does not own are ignored, as the registry (:mod:`fmutools.registry`) asks every
        package with the full list.

    Returns
    -------
    list of FmuSpec
        The owned ones, in the order of ``models`` (or of :data:`MODELS`).
    """
    names = list(MODELS) if models is None else [m for m in models if m in MODELS]
    return [law_spec(design(MODELS[name]), name) for name in names]


def controller_identifier(law: DiscreteLaw, model_identifier: str | None = None) -> str:
    """The modelIdentifier of a law's FMU: ``controller_<law name>`` unless given.

    Parameters
    ----------
    law : DiscreteLaw
        The law.
    model_identifier : str, optional
        Wanted identifier, used as is when given.

    Returns
    -------
    str
        A C identifier (characters other than letters, digits and ``_`` become ``_``).
    """
    if model_identifier:
        return model_identifier
    return PREFIX + re.sub(r"\W", "_", law.name)


def build_controller_fmu(law, out_dir, model_identifier: str | None = None) -> BuildReport:
    """Build and validate the (Python) controller FMU of a law or of a law file.

    The controller twin of :func:`structfmu.fmuspec.build_structure_fmu`; ``jitterfmu
    build --controller LAW.npz`` builds it and its native twin.

    Parameters
    ----------
    law : DiscreteLaw or path-like
        The law, or a file written by :func:`ctrlfmu.law.save_law`.
    out_dir : path-like
        Destination folder.
    model_identifier : str, optional
        FMI modelIdentifier and file stem; default ``controller_<law name>``.

    Returns
    -------
    fmutools.build.BuildReport
        The FMU path and its validation problems (one line each).

    Raises
    ------
    ctrlfmu.law.LawFileError
        If the file is not a control law file.
    FileNotFoundError
        If the file does not exist.
    """
    if not isinstance(law, DiscreteLaw):
        law = load_law(Path(law))
    path = build_fmu(law_spec(law, controller_identifier(law, model_identifier)), out_dir)
    return BuildReport((path,), tuple(validate_fmu(path, strict=True)))
