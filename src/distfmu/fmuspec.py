"""FMU specifications of the disturbance package: ``disturbance`` and ``excitation``.

:func:`spec_with_source` makes a disturbance FMU that carries its own source (a measured
``Table``, a ``BandLimitedRandom``, a ``Sum``...) besides the presets.
"""

from __future__ import annotations

from distfmu.custom import CUSTOM_PRESET, SOURCE_FILE, source_to_json
from fmutools.build import FmuSpec

__all__ = ["MODELS", "spec_with_source", "specs"]

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


def spec_with_source(source, model_identifier: str, description: str = "",
                     step_size: float | None = 1e-3) -> FmuSpec:
    """Specification of a disturbance FMU whose ``preset`` defaults to ``source``.

    The source is stored as data (:func:`distfmu.custom.source_to_json`) in the FMU's
    ``resources/``; the ``preset`` parameter starts at ``"custom"``, which selects it, and
    still accepts every preset name.  The native build carries the same source.

    Parameters
    ----------
    source : Source
        A time-driven source of :mod:`distfmu.sources` or a ``Sum`` of them.
    model_identifier : str
        FMI modelIdentifier and file stem of the FMU.
    description : str
        One-line model description; default names the source type.
    step_size : float or None
        Default communication step (s).

    Returns
    -------
    FmuSpec
        Build it with ``fmutools.build.build_fmu`` or ``nativefmu.build.build_native``.
    """
    return FmuSpec(model_identifier=model_identifier, slave_class=_SLAVES["disturbance"],
                   resources={SOURCE_FILE: source_to_json(source)},
                   description=description or f"{type(source).__name__} disturbance source "
                                              "as force/torque at its mount",
                   step_size=step_size, init_kwargs={"default_preset": CUSTOM_PRESET})
