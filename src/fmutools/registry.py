"""The suite's FMUs: which package provides which, and building them all.

:data:`PROVIDERS` maps each FMU package to the ``specs`` function of its ``fmuspec``
module, ``specs(models: list[str] | None) -> list[FmuSpec]``: ``models=None`` means
all of the package's FMUs, otherwise the package returns the requested ones it owns
and ignores the others.  :func:`build_all` builds and validates them (``jitterfmu
build``); :func:`fmutools.ensure.ensure_fmus` rebuilds only the missing or stale ones
(by :func:`sources_hash`).
"""

from __future__ import annotations

import hashlib
import importlib.util
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from acsfmu import fmuspec as acsfmu_specs
from ctrlfmu import fmuspec as ctrlfmu_specs
from distfmu import fmuspec as distfmu_specs
from piezofmu import fmuspec as piezofmu_specs
from structfmu import fmuspec as structfmu_specs

from fmutools.build import BuildReport, FmuSpec, build_fmu
from fmutools.validate import validate_fmu

__all__ = ["PROVIDERS", "PACKAGES", "collect_specs", "build_all", "sources_hash",
           "BuildReport", "UnknownModelError"]

#: FMU package -> its ``specs(models)`` function, in build order.
PROVIDERS: Mapping[str, Callable[[list[str] | None], list[FmuSpec]]] = {
    "structfmu": structfmu_specs.specs,
    "piezofmu": piezofmu_specs.specs,
    "acsfmu": acsfmu_specs.specs,
    "distfmu": distfmu_specs.specs,
    "ctrlfmu": ctrlfmu_specs.specs,
}

#: Packages whose FMUs the registry builds, in build order.
PACKAGES = tuple(PROVIDERS)

#: Packages whose sources make an FMU stale when they change (the runtime bundled into
#: every FMU, this tooling with the C loader, and the FMU packages).
SOURCE_PACKAGES = ("fmukit", "fmutools", *PACKAGES)


class UnknownModelError(KeyError):
    """A requested model is provided by no package."""

    def __str__(self) -> str:
        return str(self.args[0])


def collect_specs(models: Sequence[str] | None = None,
                  packages: Sequence[str] = PACKAGES) -> list[FmuSpec]:
    """Return the FMU specs of all packages (or of the named models).

    Parameters
    ----------
    models : sequence of str, optional
        modelIdentifiers to build; None for all.
    packages : sequence of str
        Keys of :data:`PROVIDERS` to search.

    Raises
    ------
    UnknownModelError
        If a requested model is provided by no package.
    ValueError
        If two specs share a modelIdentifier.
    """
    wanted = list(models) if models else None
    out: list[FmuSpec] = []
    for pkg in packages:
        specs = PROVIDERS[pkg]
        try:
            found = specs(wanted)
        except KeyError:
            found = []  # the package does not own any requested model
        out += [s for s in found if wanted is None or s.model_identifier in wanted]
    seen: dict[str, FmuSpec] = {}
    for spec in out:
        if spec.model_identifier in seen:
            raise ValueError(f"modelIdentifier {spec.model_identifier!r} is used by two FMUs "
                             f"({seen[spec.model_identifier].slave_class} and "
                             f"{spec.slave_class}); expected unique identifiers")
        seen[spec.model_identifier] = spec
    if wanted:
        missing = [m for m in wanted if m not in seen]
        if missing:
            raise UnknownModelError(f"no package provides the models {missing}; known: "
                                    f"{sorted(s.model_identifier for s in collect_specs())}")
    return out


def build_all(out_dir: str | Path, models: Sequence[str] | None = None, *,
              progress: Callable[[str], None] | None = None) -> BuildReport:
    """Build and validate every FMU (or the named ones) into ``out_dir``.

    Parameters
    ----------
    out_dir : str or Path
        Destination folder.
    models : sequence of str, optional
        modelIdentifiers to build; None for all.
    progress : callable, optional
        Called with one line per FMU.

    Returns
    -------
    BuildReport
        Built FMU paths and validation problems (one line each).
    """
    specs = collect_specs(models)
    fmus, problems = [], []
    for i, spec in enumerate(specs, start=1):
        path = build_fmu(spec, out_dir)
        found = validate_fmu(path, strict=True)  # the project's conventions too
        fmus.append(path)
        problems += found
        if progress is not None:
            status = "ok" if not found else f"{len(found)} problem(s)"
            progress(f"[{i}/{len(specs)}] {spec.model_identifier}: {path} {status}")
    return BuildReport(tuple(fmus), tuple(problems))


def sources_hash(packages: Sequence[str] = SOURCE_PACKAGES) -> str:
    """Hash of every source file of the named packages (hex SHA-256).

    Parameters
    ----------
    packages : sequence of str
        Importable package names; default :data:`SOURCE_PACKAGES`.
    """
    h = hashlib.sha256()
    for pkg in packages:
        spec = importlib.util.find_spec(pkg)
        root = Path(list(spec.submodule_search_locations)[0])
        for path in sorted(root.rglob("*")):
            if path.suffix in (".py", ".c", ".h", ".npz", ".csv") and "__pycache__" not in \
                    path.parts:
                h.update(str(path.relative_to(root.parent)).encode())
                h.update(path.read_bytes())
    return h.hexdigest()
