"""FMU specification of the disturbance package: one FMU, ``disturbance``."""

from __future__ import annotations

from fmutools.build import FmuSpec

__all__ = ["MODELS", "specs"]

#: modelIdentifier -> one-line description.
MODELS: dict[str, str] = {
    "disturbance": "EOS AM-1 disturbance event (preset) as force/torque at its mount",
    "excitation": "two sine-burst voltage channels (test excitation of active members)",
}
_SLAVES = {"disturbance": "distfmu.slave:DisturbanceSlave",
           "excitation": "distfmu.excitation:ExcitationSlave"}


def specs(models: list[str] | None = None) -> list[FmuSpec]:
    """Return the specifications of the disturbance FMUs.

    Parameters
    ----------
    models : list of str or None
        Model identifiers wanted; None for all.  Other packages' names are ignored.

    Returns
    -------
    list of FmuSpec
        ``disturbance`` and ``excitation`` when wanted.
    """
    names = list(MODELS) if models is None else [m for m in models if m in MODELS]
    return [FmuSpec(model_identifier=name, slave_class=_SLAVES[name],
                    description=MODELS[name], step_size=1e-3)
            for name in names]
