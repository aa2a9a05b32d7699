"""Build the suite's FMUs on demand, native by default, never running stale ones.

An FMU folder holds the native (C99) FMUs, which run in any FMI tool without Python,
and, in its ``python/`` subfolder, their Python twins (pythonfmu), from which the
native ones take their model description and model data.  :func:`ensure_fmus` builds
the named FMUs that are missing or were built from other sources (a hash of the sources,
kept per folder in ``.sources``), so ``jitterfmu reproduce``, ``make demo`` and the
tests never run stale FMUs.  A scenario chooses the build it runs with
``[experiment] fmu_kind`` (``native`` or ``python``; :func:`orchestrator.cosim.find_fmu`).
"""

from __future__ import annotations

import hashlib
import json
import shutil
from collections.abc import Callable, Iterable, Mapping
from contextlib import contextmanager
from dataclasses import fields
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: builds are not serialised
    fcntl = None

from fmutools import FMU_KINDS, PYTHON_SUBDIR
from fmutools.atomic import replaced_when_done
from fmutools.build import FmuSpec, build_fmu
from fmutools.registry import SOURCE_PACKAGES, collect_specs, sources_hash
from nativefmu.build import build_native
from nativefmu.data import NativeUnsupportedError

__all__ = ["ensure_fmus", "record_built", "current_fmus"]



def ensure_fmus(names: Iterable[str], fmu_dir="fmus", progress: Callable | None = None,
                extra: Mapping[str, Callable | FmuSpec] | None = None,
                kind: str = "native") -> dict:
    """Paths of the named FMUs of one build, building missing or stale ones.

    Parameters
    ----------
    names : iterable of str
        Model identifiers (e.g. ``"truss10_structure"``).
    fmu_dir : path-like
        FMU folder: the native FMUs in it, the Python ones in ``fmu_dir/python/``.
    progress : callable, optional
        Called with one line of text per FMU built.
    extra : mapping of str to callable or FmuSpec, optional
        FMUs the registry does not know.  ``name -> () -> FmuSpec`` (e.g. a structure
        built from a variant of a built-in model) is stamped and rebuilt like the others,
        the spec made only when the FMU is missing or stale.  ``name -> FmuSpec`` (a
        spec that is cheap to make, e.g. a controller from a law designed at run time)
        is also rebuilt when the spec itself changed (its content joins the stamp).
    kind : {"native", "python"}
        Which build to return.  ``"native"`` builds the Python FMUs first (the native
        build reads them); an FMU without a C kernel is then the Python one, copied.

    Returns
    -------
    dict of str to Path
        ``name -> path`` of the requested build.
    """
    if kind not in FMU_KINDS:
        raise ValueError(f"FMU kind {kind!r} is unknown; expected one of "
                         f"{', '.join(FMU_KINDS)}")
    fmu_dir = Path(fmu_dir)
    names = list(dict.fromkeys(names))
    extra = dict(extra or {})
    py_dir = fmu_dir / PYTHON_SUBDIR
    python = _ensure(names, py_dir, progress, extra, SOURCE_PACKAGES,
                     lambda spec: build_fmu(spec, py_dir))
    if kind == "python":
        return python

    def native(spec):
        try:
            return build_native(spec, fmu_dir, python_fmu=python[spec.model_identifier],
                                windows=False)
        except NativeUnsupportedError as exc:
            if progress:
                progress(f"{spec.model_identifier}: no native form ({exc}); the Python FMU "
                         "is used")
            return Path(shutil.copy(python[spec.model_identifier], fmu_dir))
    return _ensure(names, fmu_dir, progress, extra, NATIVE_PACKAGES, native)


NATIVE_PACKAGES = (*SOURCE_PACKAGES, "nativefmu")


def record_built(folder, names: Iterable[str], kind: str) -> None:
    """Stamp FMUs built outside :func:`ensure_fmus` (``jitterfmu build``) as current.

    Parameters
    ----------
    folder : path-like
        The folder holding them (an FMU folder, or its ``python/`` for ``"python"``).
    names : iterable of str
        Model identifiers just built from the current sources.
    kind : {"native", "python"}
        Which build they are.
    """
    current = sources_hash(NATIVE_PACKAGES if kind == "native" else SOURCE_PACKAGES)
    with _locked(Path(folder)):   # two builds into one folder keep each other's stamps
        _write_stamps(Path(folder), {**_stamps(Path(folder)), **{n: current for n in names}})


def current_fmus(folder, names: Iterable[str], kind: str) -> list[str]:
    """The named FMUs in ``folder`` built from today's sources (nothing to rebuild).

    The key is the content of the sources the FMUs are built from (:func:`sources_hash`
    of the packages, kept per folder in ``.sources`` by :func:`ensure_fmus` and
    :func:`record_built`); an FMU whose file is missing or whose sources changed since
    is not current.

    Parameters
    ----------
    folder : path-like
        An FMU folder (or its ``python/`` for ``"python"``).
    names : iterable of str
        Model identifiers.
    kind : {"native", "python"}
        Which build the folder holds.

    Returns
    -------
    list of str
        The current ones, in the order of ``names``.
    """
    folder = Path(folder)
    current = sources_hash(NATIVE_PACKAGES if kind == "native" else SOURCE_PACKAGES)
    stamps = _stamps(folder)
    return [n for n in names if (folder / f"{n}.fmu").is_file() and stamps.get(n) == current]


def _stamps(folder: Path) -> dict:
    """``{name: sources hash}`` of the FMUs built in ``folder`` (``.sources``)."""
    stamp_file = folder / ".sources"
    return json.loads(stamp_file.read_text()) if stamp_file.is_file() else {}


def _write_stamps(folder: Path, stamps: dict) -> None:
    with replaced_when_done(folder / ".sources") as tmp:
        tmp.write_text(json.dumps(stamps, indent=1))


@contextmanager
def _locked(folder: Path):
    """Hold an exclusive lock on ``folder`` (another process building there waits)."""
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / ".lock", "a+") as f:
        if fcntl is not None:
            fcntl.flock(f, fcntl.LOCK_EX)
        yield


def _ensure(names, folder: Path, progress, extra, packages, build) -> dict:
    """Build the missing or stale ``names`` into ``folder`` with ``build(spec)``; two
    processes that ensure the same folder take turns (the second finds them built)."""
    with _locked(folder):
        return _ensure_unlocked(names, folder, progress, extra, packages, build)


def _ensure_unlocked(names, folder: Path, progress, extra, packages, build) -> dict:
    stamps = _stamps(folder)
    current = sources_hash(packages)
    want = {n: _stamp(current, extra.get(n)) for n in names}
    todo = [n for n in names
            if not (folder / f"{n}.fmu").is_file() or stamps.get(n) != want[n]]
    if todo:
        known = [n for n in todo if n not in extra]
        # an unknown name raises UnknownModelError, listing the FMUs the project knows
        specs = {s.model_identifier: s for s in collect_specs(known)} if known else {}
        for n in todo:
            if progress:
                progress(f"building {folder / n}.fmu")
            spec = specs.get(n) or extra[n]
            build(spec() if callable(spec) else spec)
            stamps[n] = want[n]
            _write_stamps(folder, stamps)
    return {n: folder / f"{n}.fmu" for n in names}


def _stamp(sources: str, entry) -> str:
    """The stamp of an FMU: the sources hash, and for a ready spec its content too."""
    return sources if entry is None or callable(entry) else f"{sources}+{_spec_digest(entry)}"


def _spec_digest(spec: FmuSpec) -> str:
    """SHA-256 of what a build reads from ``spec`` (fields and resource contents)."""
    h = hashlib.sha256()
    for f in fields(spec):
        value = getattr(spec, f.name)
        if f.name == "resources":
            for name in sorted(value):
                data = value[name]
                data = data if isinstance(data, bytes) else Path(data).read_bytes()
                h.update(f"{name}:{len(data)}:".encode())
                h.update(data)
        else:
            h.update(f"{f.name}={value!r};".encode())
    return h.hexdigest()
