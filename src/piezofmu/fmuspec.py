"""FMU specifications of the piezo package: one FMU per stack preset."""

from __future__ import annotations

from fmutools.build import FmuSpec

__all__ = ["MODELS", "UnknownModelError", "specs"]

#: modelIdentifier -> stack preset.
MODELS: dict[str, str] = {
    "piezo_p243_30": "P-243.30",
    "piezo_p243_40": "P-243.40",
    "piezo_p845_37": "P-845.37",
}

_USE = {
    "P-243.30": "longeron active member (Trek 50/750 amplifier)",
    "P-243.40": "diagonal active member (Trek 50/750 amplifier)",
    "P-845.37": "isolator strut (P-865.10 amplifier)",
}


class UnknownModelError(KeyError):
    """A requested model identifier is not one of the piezo FMUs."""

    def __str__(self) -> str:
        return str(self.args[0])


def specs(models: list[str] | None = None) -> list[FmuSpec]:
    """Return the specifications of the piezo FMUs.

    Parameters
    ----------
    models : list of str or None
        Model identifiers wanted (see `MODELS`); None for all.  Names of other packages'
        models are ignored, so the project registry can pass one mixed list to every
        package.

    Returns
    -------
    list of FmuSpec
        The wanted piezo FMUs, in the order of `models` (or of `MODELS`).

    Raises
    ------
    UnknownModelError
        If `models` names no piezo FMU at all.
    """
    if models is None:
        names = list(MODELS)
    else:
        names = [m for m in models if m in MODELS]
        if not names:
            raise UnknownModelError(f"none of the models {list(models)} is a piezo FMU; "
                                    f"known: {', '.join(MODELS)}")
    return [
        FmuSpec(
            model_identifier=name,
            slave_class="piezofmu.slave:PiezoSlave",
            description=f"Piezo stack {MODELS[name]} with amplifier: {_USE[MODELS[name]]}",
            step_size=1e-3,
            init_kwargs={"preset_name": MODELS[name]},
        )
        for name in names
    ]
