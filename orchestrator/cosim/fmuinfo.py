"""What the master reads from an FMU without instantiating it, and where FMUs are found."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from fmpy import read_model_description

from fmutools import PYTHON_SUBDIR
from fmutools.archive import model_identifier_problem
from fmutools.validate import archive_problem

from ..files import sha256_file
from ..scenario import Scenario, ScenarioError, closest

__all__ = ["FmuInfo", "Variable", "find_fmu", "read_fmu_info"]


@dataclass(frozen=True)
class Variable:
    """One scalar variable of an FMU's model description."""

    name: str
    vr: int
    type: str
    causality: str
    variability: str
    unit: str | None
    start: object = None
    #: declared ``min`` and ``max`` of a Real (the range outside which its value means
    #: the model left its validity, e.g. a diverging loop); -inf and inf when undeclared
    min: float = -math.inf
    max: float = math.inf


@dataclass(frozen=True)
class FmuInfo:
    """What the master needs from an FMU without instantiating it.

    Attributes
    ----------
    path : Path
    sha256 : str
    model_identifier, guid : str
    variables : dict of str to Variable
    feedthrough : dict of str to frozenset of str
        Each output's direct input dependencies.
    can_get_set_state : bool
    fmi_version : str
        ``"2.0"`` or ``"3.0"``.  An FMI 3.0 FMU's Float64, Int32, Boolean and String
        variables have the types Real, Integer, Boolean and String here, as in FMI 2.0.
    """

    path: Path
    sha256: str
    model_identifier: str
    guid: str
    variables: dict
    feedthrough: dict
    can_get_set_state: bool
    model_description: object = field(repr=False, compare=False, default=None)
    fmi_version: str = "2.0"


#: FMI 3.0 variable types the master exchanges, as the FMI 2.0 types it knows.
FMI3_AS_FMI2 = {"Float64": "Real", "Int32": "Integer", "Boolean": "Boolean",
                "String": "String"}


_INFO_CACHE: dict = {}


def _declared_range(path: Path, v) -> tuple:
    """``(min, max)`` declared on a Real (Float64), as floats (-inf, inf where undeclared)."""
    bounds = []
    for attr, default in (("min", -math.inf), ("max", math.inf)):
        text = getattr(v, attr, None) if v.type in ("Real", "Float64") else None
        try:
            bounds.append(default if text is None else float(text))
        except ValueError:
            raise ScenarioError(f"FMU {str(path)!r}: variable {v.name!r} has {attr}="
                                f"{text!r}, which is not a number; fix its model "
                                "description") from None
    if bounds[0] > bounds[1]:
        raise ScenarioError(f"FMU {str(path)!r}: variable {v.name!r} has min {bounds[0]!r} "
                            f"above max {bounds[1]!r}; fix its model description")
    return tuple(bounds)


def read_fmu_info(path) -> FmuInfo:
    """Read an FMU's model description and dependency structure (cached per file).

    Parameters
    ----------
    path : path-like
        The ``.fmu`` file.

    Returns
    -------
    FmuInfo
    """
    path = Path(path).resolve()
    st = path.stat()
    key = (str(path), st.st_mtime_ns, st.st_size)
    if key in _INFO_CACHE:
        return _INFO_CACHE[key]
    problem = archive_problem(path)
    if problem is not None:
        raise ScenarioError(problem)
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:  # noqa: BLE001 - fmpy raises anything on a bad file
        raise ScenarioError(f"FMU {str(path)!r} has no readable modelDescription.xml: {exc}")
    if md.coSimulation is None:
        raise ScenarioError(f"FMU {str(path)!r} is model exchange only; this master runs "
                            "FMI 2.0 and 3.0 co-simulation FMUs: export it for co-simulation")
    problem = model_identifier_problem(md.coSimulation.modelIdentifier)
    if problem is not None:
        raise ScenarioError(f"FMU {str(path)!r}: {problem}")
    variables = {}
    fmi3 = md.fmiVersion == "3.0"
    for v in md.modelVariables:
        unit = v.unit or (v.declaredType.unit if v.declaredType is not None else None)
        vtype = FMI3_AS_FMI2.get(v.type, v.type) if fmi3 else v.type
        variables[v.name] = Variable(v.name, int(v.valueReference), vtype, v.causality,
                                     v.variability, unit, v.start,
                                     *_declared_range(path, v))
    inputs = frozenset(n for n, v in variables.items() if v.causality == "input")
    feedthrough = {}
    for u in md.outputs:
        if u.dependencies is None:  # FMI 2.0: no attribute means "depends on all inputs"
            feedthrough[u.variable.name] = inputs
        else:
            feedthrough[u.variable.name] = frozenset(
                d.name for d in u.dependencies if d.name in inputs)
    for n, v in variables.items():
        if v.causality == "output" and n not in feedthrough:
            feedthrough[n] = inputs
    info = FmuInfo(path, sha256_file(path), md.coSimulation.modelIdentifier, md.guid,
                   variables, feedthrough, bool(md.coSimulation.canGetAndSetFMUstate), md,
                   md.fmiVersion)
    _INFO_CACHE[key] = info
    return info


def _search_dirs(scenario: Scenario, fmu_dir=None) -> list:
    dirs = []
    if fmu_dir is not None:
        dirs.append(Path(fmu_dir))
    if scenario.base_dir is not None:
        base = Path(scenario.base_dir)
        dirs += [base / "fmus", base, base.parent / "fmus"]
    dirs += [Path.cwd() / "fmus", Path.cwd()]
    seen, out = set(), []
    for d in dirs:
        r = d.resolve()
        if r not in seen:
            seen.add(r)
            out.append(d)
    return out


def find_fmu(name: str, scenario: Scenario, fmu_dir=None) -> Path:
    """Resolve an FMU name or path of a scenario to an existing ``.fmu`` file.

    A bare name ``x`` is looked up as ``x.fmu`` in `fmu_dir`, then in ``fmus/`` next to
    the scenario file, next to it, in ``fmus/`` of its parent folder, and in ``fmus/`` of
    the current folder.  A name with a suffix or a folder is a path (relative to the
    scenario folder, then the current folder).  Under ``fmu_kind = "python"`` the Python
    twin (``python/`` beside the FMU, where the Python build of the suite's FMUs lives) is
    tried before each candidate.

    Parameters
    ----------
    name : str
        FMU name or path, as the scenario's ``[fmus.X] fmu`` gives it.
    scenario : Scenario
        Gives the scenario's folder and ``experiment.fmu_kind``.
    fmu_dir : path-like, optional
        Folder searched first.

    Returns
    -------
    Path
        The FMU file.
    """
    python = scenario.experiment.fmu_kind == "python"

    def builds(path: Path) -> tuple:
        """Where ``path`` may be, its Python twin first under ``fmu_kind = "python"``."""
        return ((path.parent / PYTHON_SUBDIR / path.name,) if python else ()) + (path,)

    p = Path(name)
    if p.suffix.lower() == ".fmu" or len(p.parts) > 1:
        for cand in ([p] if p.is_absolute() else
                     [(scenario.base_dir or Path.cwd()) / p, Path.cwd() / p]):
            found = next((c for c in builds(cand) if c.is_file()), None)
            if found is not None:
                return found
        raise ScenarioError(f"FMU file {name!r} does not exist")
    dirs = _search_dirs(scenario, fmu_dir)
    for d in dirs:
        found = next((c for c in builds(d / f"{name}.fmu") if c.is_file()), None)
        if found is not None:
            return found
    other = next((d for d in dirs if (d / PYTHON_SUBDIR / f"{name}.fmu").is_file()), None)
    if other is not None:
        raise ScenarioError(
            f"FMU {name!r} has only a Python build (in {other / PYTHON_SUBDIR}); build the "
            "native FMUs (jitterfmu build) or run with the Python ones (--python-fmus, or "
            "fmu_kind = \"python\" in [experiment])")
    known = sorted({f.stem for d in dirs if d.is_dir() for f in d.glob("*.fmu")})
    where = ", ".join(str(d) for d in dirs)
    raise ScenarioError(
        f"unknown FMU {name!r}: no {name}.fmu in {where}{closest(name, known)}"
        + ("" if known else "; build the FMUs first (jitterfmu build) or pass --fmu-dir")
    )
