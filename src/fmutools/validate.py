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
from xml.etree.ElementTree import ParseError, fromstring

from fmpy.validation import validate_fmu as fmpy_validate

from fmukit.modeldesc import check_model_description
from fmutools.archive import (
    ArchiveError,
    check_directory,
    model_identifier_problem,
    read_member,
)

__all__ = ["FmuCheck", "archive_problem", "check_fmu", "validate_fmu"]


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
    problem = archive_problem(path)
    if problem is not None:
        return FmuCheck(errors=(problem,))
    with zipfile.ZipFile(path) as zf:
        names = set(zf.namelist())
        xml = read_member(zf, "modelDescription.xml", f"FMU {path}")
    cs = fromstring(xml).find("CoSimulation")
    problem = None if cs is None else model_identifier_problem(cs.get("modelIdentifier"))
    if problem is not None:
        return FmuCheck(errors=(f"{path.name}: {problem}",))
    errors = [f"{path.name}: {p}" for p in fmpy_validate(str(path))]
    if errors:  # the conventions need a readable model description
        return FmuCheck(errors=tuple(errors))
    warnings = [f"{path.name}: {p}" for p in check_model_description(xml)]
    if cs is not None:
        platform = "x86_64-linux" if fromstring(xml).get("fmiVersion") == "3.0" else "linux64"
        binary = f"binaries/{platform}/{cs.get('modelIdentifier')}.so"
        if binary not in names:
            warnings.append(f"{path.name}: {binary} is missing; expected the Linux binary")
    return FmuCheck(tuple(errors), tuple(warnings))


def archive_problem(path) -> str | None:
    """Why the file at ``path`` cannot be read as an FMI 2.0 or 3.0 FMU at all, or None.

    It must exist, be a zip archive within the size limits whose member paths stay
    inside it (:mod:`fmutools.archive`), and hold a ``modelDescription.xml`` of FMI 2.0.

    Parameters
    ----------
    path : path-like
        ``.fmu`` file.

    Returns
    -------
    str or None
        One sentence naming the file, or None.
    """
    path = Path(path)
    where = f"FMU {str(path)!r}"
    if not path.is_file():
        return f"{where} does not exist"
    try:
        with zipfile.ZipFile(path) as zf:
            check_directory(zf, where)
            if "modelDescription.xml" not in zf.namelist():
                return f"{where} has no modelDescription.xml"
            xml = read_member(zf, "modelDescription.xml", where)
    except zipfile.BadZipFile:
        return f"{where} is not a zip archive"
    except ArchiveError as exc:
        return str(exc)
    try:
        version = fromstring(xml).get("fmiVersion")
    except ParseError as exc:
        return f"{where}: modelDescription.xml is not well-formed XML ({exc})"
    if version not in ("2.0", "3.0"):
        return (f"{where} is FMI {version}, and this master runs FMI 2.0 and 3.0 FMUs only; "
                "export the model as an FMI 2.0 or 3.0 co-simulation FMU")
    return None


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
