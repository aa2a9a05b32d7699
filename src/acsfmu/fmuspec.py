"""FMU specification of the attitude-control package: one FMU, ``acs``."""

from __future__ import annotations

from fmutools.build import FmuSpec

__all__ = ["MODELS", "specs"]

#: modelIdentifier -> one-line description.
MODELS: dict[str, str] = {
    "acs": "Three-axis PID attitude control with reaction wheels (10 Hz, delayed output)",
}


def specs(models: list[str] | None = None) -> list[FmuSpec]:
    """Return the specifications of the attitude-control FMUs.

    Parameters
    ----------
    models : list of str or None
        Model identifiers wanted; None for all.  Other packages' names are ignored.

    Returns
    -------
    list of FmuSpec
        ``[acs]`` when wanted, else empty.
    """
    names = list(MODELS) if models is None else [m for m in models if m in MODELS]
    return [FmuSpec(model_identifier=name, slave_class="acsfmu.slave:AcsSlave",
                    description=MODELS[name], step_size=0.1)
            for name in names]
