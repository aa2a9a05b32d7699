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

from ctrlfmu.designs import DESIGNS, design
from ctrlfmu.law import DiscreteLaw, law_bytes
from fmutools.build import FmuSpec

__all__ = ["MODELS", "specs", "law_spec"]

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
