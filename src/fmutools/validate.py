"""Validate an FMU: FMI 2.0 errors apart from the project's own conventions.

:func:`check_fmu` returns both lists; :func:`validate_fmu` returns the problems that
fail a check (every one when ``strict``, the FMI 2.0 errors only otherwise).  A valid
FMI 2.0 FMU from elsewhere (say the Reference FMUs, whose ``time`` has no unit and
whose outputs have no ``dependencies`` attribute) passes a non-strict check; the
project's own FMUs are checked strictly when they are built.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree.ElementTree import fromstring

from fmpy.validation import validate_fmu as fmpy_validate

from fmukit.modeldesc import check_model_description

__all__ = ["FmuCheck", "check_fmu", "validate_fmu"]


@dataclass(frozen=True)
class FmuCheck:
    """What is wrong with one FMU; unpacks as ``errors, warnings = check``.

    Attributes
    ----------
    errors : tuple of str
        Breaches of FMI 2.0 (fmpy's validation: schema, names, ModelStructure, start
        values, causality/variability), or a file that is no FMU at all.
    warnings : tuple of str
        Breaches of this project's conventions (a unit on every Real, a
        ``dependencies`` attribute on every output, ``canGetAndSetFMUstate``,
        ``InitialUnknowns``, a linux64 binary).
    """

    errors: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()

    def __iter__(self):
        return iter((self.errors, self.warnings))

    def problems(self, strict: bool = False) -> list[str]:
        """The errors, and with ``strict`` the warnings too."""
        return list(self.errors) + (list(self.warnings) if strict else [])


def check_fmu(path: str | Path) -> FmuCheck:
    """Check the FMU at ``path`` against FMI 2.0 and the project's conventions.

    Runs :func:`fmpy.validation.validate_fmu` (FMI errors) and
    :func:`fmukit.modeldesc.check_model_description` plus the linux64 binary check
    (conventions).

    Parameters
    ----------
    path : str or Path
        ``.fmu`` file.

    Returns
    -------
    FmuCheck
        One sentence per problem, each prefixed with the file name.
    """
    path = Path(path)
    if not path.is_file():
        return FmuCheck(errors=(f"FMU {path} does not exist",))
    try:
        with zipfile.ZipFile(path) as zf:
            names = set(zf.namelist())
            xml = zf.read("modelDescription.xml") if "modelDescription.xml" in names else None
    except zipfile.BadZipFile:
        return FmuCheck(errors=(f"FMU {path} is not a zip archive",))
    if xml is None:
        return FmuCheck(errors=(f"FMU {path} has no modelDescription.xml",))
    errors = [f"{path.name}: {p}" for p in fmpy_validate(str(path))]
    if errors:  # the conventions need a readable model description
        return FmuCheck(errors=tuple(errors))
    warnings = [f"{path.name}: {p}" for p in check_model_description(xml)]
    cs = fromstring(xml).find("CoSimulation")
    if cs is not None:
        binary = f"binaries/linux64/{cs.get('modelIdentifier')}.so"
        if binary not in names:
            warnings.append(f"{path.name}: {binary} is missing; expected the Linux binary")
    return FmuCheck(tuple(errors), tuple(warnings))


def validate_fmu(path: str | Path, *, strict: bool = True) -> list[str]:
    """Return the problems of the FMU at ``path`` that fail the check, one sentence each.

    Parameters
    ----------
    path : str or Path
        ``.fmu`` file.
    strict : bool
        Also count the project's conventions (the default: what the build requires
        of the project's own FMUs); False for FMI 2.0 errors only.

    Returns
    -------
    list of str
        Empty when the FMU passes.
    """
    return check_fmu(path).problems(strict)
