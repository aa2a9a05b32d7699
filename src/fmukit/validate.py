"""Validate a built FMU: fmpy's validation plus the project's own checks."""

from __future__ import annotations

import zipfile
from pathlib import Path

__all__ = ["validate_fmu"]


def validate_fmu(path: str | Path) -> list[str]:
    """Return every problem of the FMU at ``path``, one sentence each.

    Runs :func:`fmpy.validation.validate_fmu` (schema, names, ModelStructure, start
    values, causality/variability, units) and
    :func:`fmukit.modeldesc.check_model_description` (dependencies on every output,
    a defined unit on every Real, ``canGetAndSetFMUstate``, ``InitialUnknowns``), and
    checks that the Linux binary named after the modelIdentifier exists.

    Parameters
    ----------
    path : str or Path
        ``.fmu`` file.

    Returns
    -------
    list of str
        Empty when the FMU has no problem.
    """
    from fmpy.validation import validate_fmu as fmpy_validate

    from fmukit.modeldesc import check_model_description

    path = Path(path)
    if not path.is_file():
        return [f"FMU {path} does not exist"]
    try:
        with zipfile.ZipFile(path) as zf:
            names = set(zf.namelist())
            xml = zf.read("modelDescription.xml") if "modelDescription.xml" in names else None
    except zipfile.BadZipFile:
        return [f"FMU {path} is not a zip archive"]
    if xml is None:
        return [f"FMU {path} has no modelDescription.xml"]
    problems = [f"{path.name}: {p}" for p in fmpy_validate(str(path))]
    problems += [f"{path.name}: {p}" for p in check_model_description(xml)]
    from xml.etree.ElementTree import fromstring

    cs = fromstring(xml).find("CoSimulation")
    if cs is not None:
        binary = f"binaries/linux64/{cs.get('modelIdentifier')}.so"
        if binary not in names:
            problems.append(f"{path.name}: {binary} is missing; expected the Linux binary")
    return problems
