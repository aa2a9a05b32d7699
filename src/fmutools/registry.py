"""The suite's FMUs: which package provides which, and building them all.

:data:`PROVIDERS` maps each FMU package to the ``specs`` function of its ``fmuspec``
module, ``specs(models: list[str] | None) -> list[FmuSpec]``: ``models=None`` means
all of the package's FMUs, otherwise the package returns the requested ones it owns
and ignores the others.  :func:`build_all` builds and validates them (``jitterfmu
build``); :func:`ensure_fmus` rebuilds only the missing or stale ones (a hash of the
sources, kept in ``fmu_dir/.sources``), so commands like ``jitterfmu reproduce`` and
``make demo`` never run stale FMUs.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from acsfmu import fmuspec as acsfmu_specs
from ctrlfmu import fmuspec as ctrlfmu_specs
from distfmu import fmuspec as distfmu_specs
from piezofmu import fmuspec as piezofmu_specs
from structfmu import fmuspec as structfmu_specs

from fmutools.build import BuildReport, FmuSpec, build_fmu
from fmutools.validate import validate_fmu

__all__ = ["PROVIDERS", "PACKAGES", "collect_specs", "build_all", "ensure_fmus",
           "sources_hash", "BuildReport", "UnknownModelError"]

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


def sources_hash() -> str:
    """Hash of every source file of :data:`SOURCE_PACKAGES` (hex SHA-256)."""
    h = hashlib.sha256()
    for pkg in SOURCE_PACKAGES:
        spec = importlib.util.find_spec(pkg)
        root = Path(list(spec.submodule_search_locations)[0])
        for path in sorted(root.rglob("*")):
            if path.suffix in (".py", ".c", ".h", ".npz", ".csv") and "__pycache__" not in \
                    path.parts:
                h.update(str(path.relative_to(root.parent)).encode())
                h.update(path.read_bytes())
    return h.hexdigest()


def ensure_fmus(names, fmu_dir="fmus", progress=None, extra=None) -> dict:
    """Paths of the named FMUs in ``fmu_dir``, building missing or stale ones.

    Parameters
    ----------
    names : iterable of str
        Model identifiers (e.g. ``"truss10_structure"``).
    fmu_dir : path-like
        Folder of built FMUs.
    progress : callable, optional
        Called with one line of text per FMU built.
    extra : mapping of str to callable, optional
        FMUs the registry does not know, as ``name -> () -> FmuSpec`` (e.g. a structure
        built from a variant of a built-in model); stamped and rebuilt like the others,
        the spec made only when the FMU is missing or stale.

    Returns
    -------
    dict of str to Path
    """
    fmu_dir = Path(fmu_dir)
    fmu_dir.mkdir(parents=True, exist_ok=True)
    stamp_file = fmu_dir / ".sources"
    stamps = json.loads(stamp_file.read_text()) if stamp_file.is_file() else {}
    current = sources_hash()
    names = list(dict.fromkeys(names))
    todo = [n for n in names
            if not (fmu_dir / f"{n}.fmu").is_file() or stamps.get(n) != current]
    extra = dict(extra or {})
    if todo:
        known = [n for n in todo if n not in extra]
        specs = {s.model_identifier: s for s in collect_specs(known)} if known else {}
        missing = [n for n in known if n not in specs]
        if missing:
            raise KeyError(f"no FMU named {', '.join(missing)} in the project; run "
                           "'jitterfmu build' to list the FMUs it knows")
        for n in todo:
            if progress:
                progress(f"building {n}.fmu")
            build_fmu(specs[n] if n in specs else extra[n](), fmu_dir)
            stamps[n] = current
            tmp = stamp_file.with_suffix(".tmp")
            tmp.write_text(json.dumps(stamps, indent=1))
            tmp.replace(stamp_file)
    return {n: fmu_dir / f"{n}.fmu" for n in names}
