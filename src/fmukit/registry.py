"""Find every FMU of the project and build them all.

Each package may provide ``<package>/fmuspec.py`` with
``def specs(models: list[str] | None) -> list[FmuSpec]``; ``models=None`` means all
of the package's FMUs, otherwise the package returns the requested ones it owns
and ignores the others.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from fmukit.build import FmuSpec, build_fmu
from fmukit.validate import validate_fmu

__all__ = ["PACKAGES", "collect_specs", "build_all", "BuildReport", "UnknownModelError"]

#: Packages searched for an ``fmuspec`` module, in build order.
PACKAGES = ("structfmu", "piezofmu", "acsfmu", "distfmu", "ctrlfmu")


class UnknownModelError(KeyError):
    """A requested model is provided by no package."""

    def __str__(self) -> str:
        return str(self.args[0])


@dataclass(frozen=True)
class BuildReport:
    """Result of :func:`build_all`: built FMUs and one line per problem."""

    fmus: tuple[Path, ...]
    problems: tuple[str, ...]

    def __iter__(self):
        return iter((self.fmus, self.problems))


def collect_specs(models: Sequence[str] | None = None,
                  packages: Sequence[str] = PACKAGES) -> list[FmuSpec]:
    """Return the FMU specs of all packages (or of the named models).

    Parameters
    ----------
    models : sequence of str, optional
        modelIdentifiers to build; None for all.
    packages : sequence of str
        Packages to search; those without an ``fmuspec`` module are skipped.

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
        try:
            mod = importlib.import_module(f"{pkg}.fmuspec")
        except ModuleNotFoundError as exc:
            if exc.name in (pkg, f"{pkg}.fmuspec"):
                continue
            raise
        try:
            found = mod.specs(wanted)
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
