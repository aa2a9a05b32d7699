"""Where the real NASTRAN output the tests read lives (``shared/nastran`` beside the
project, see its README; used in place, never copied into the project).

Looked for, in order: ``$JITTERFMU_NASTRAN_DATA``; ``shared/nastran`` beside this
checkout; and, for a clone, beside the repository it was cloned from (so a clean clone in
a temporary folder still finds the data of its origin).
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _origin() -> Path | None:
    try:
        url = subprocess.run(["git", "-C", str(ROOT), "config", "--get", "remote.origin.url"],
                             capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None
    path = Path(url.removeprefix("file://"))
    return path.resolve() if path.is_absolute() and path.exists() else None


def nastran_data() -> Path:
    """The folder of real NASTRAN output (may not exist: the tests then say where to
    put it)."""
    env = os.environ.get("JITTERFMU_NASTRAN_DATA")
    if env:
        return Path(env)
    origin = _origin()
    for base in (ROOT, origin):
        if base is not None and (base.parent / "shared" / "nastran" / "README.md").is_file():
            return base.parent / "shared" / "nastran"
    return ROOT.parent / "shared" / "nastran"
