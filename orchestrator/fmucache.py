"""Build the project's FMUs on demand, rebuilding when the sources change.

``ensure_fmus(names, fmu_dir)`` builds the named FMUs into ``fmu_dir`` when they are
missing or were built from other sources (a hash of the project's Python sources and
C loader, kept in ``fmu_dir/.sources``), so commands like ``jitterfmu reproduce`` and
``make demo`` never run stale FMUs.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

PACKAGES = ("fmukit", "structfmu", "piezofmu", "acsfmu", "distfmu", "ctrlfmu")


def sources_hash() -> str:
    """Hash of every source file of the FMU packages."""
    import importlib.util

    h = hashlib.sha256()
    for pkg in PACKAGES:
        spec = importlib.util.find_spec(pkg)
        root = Path(list(spec.submodule_search_locations)[0])
        for path in sorted(root.rglob("*")):
            if path.suffix in (".py", ".c", ".h", ".npz", ".csv") and "__pycache__" not in \
                    path.parts:
                h.update(str(path.relative_to(root.parent)).encode())
                h.update(path.read_bytes())
    return h.hexdigest()


def ensure_fmus(names, fmu_dir="fmus", progress=None) -> dict:
    """Paths of the named FMUs in ``fmu_dir``, building missing or stale ones.

    Parameters
    ----------
    names : iterable of str
        Model identifiers (e.g. ``"truss10_structure"``).
    fmu_dir : path-like
        Folder of built FMUs.
    progress : callable, optional
        Called with one line of text per FMU built.

    Returns
    -------
    dict of str to Path
    """
    from fmukit.build import build_fmu
    from fmukit.registry import collect_specs

    fmu_dir = Path(fmu_dir)
    fmu_dir.mkdir(parents=True, exist_ok=True)
    stamp_file = fmu_dir / ".sources"
    stamps = json.loads(stamp_file.read_text()) if stamp_file.is_file() else {}
    current = sources_hash()
    names = list(dict.fromkeys(names))
    todo = [n for n in names
            if not (fmu_dir / f"{n}.fmu").is_file() or stamps.get(n) != current]
    if todo:
        specs = {s.model_identifier: s for s in collect_specs(todo)}
        missing = [n for n in todo if n not in specs]
        if missing:
            raise KeyError(f"no FMU named {', '.join(missing)} in the project; run "
                           "'jitterfmu build' to list the FMUs it knows")
        for n in todo:
            if progress:
                progress(f"building {n}.fmu")
            build_fmu(specs[n], fmu_dir)
            stamps[n] = current
            tmp = stamp_file.with_suffix(".tmp")
            tmp.write_text(json.dumps(stamps, indent=1))
            tmp.replace(stamp_file)
    return {n: fmu_dir / f"{n}.fmu" for n in names}
