"""A file written whole or not at all: the one home of write-then-rename.

Light on purpose (standard library only), so that the master's result files
(:func:`orchestrator.files.atomic_write`) and the builds (:mod:`fmutools.build`) share it
without the master importing the build tooling.
"""

from __future__ import annotations

import contextlib
import os
import uuid
from pathlib import Path

__all__ = ["replaced_when_done"]


@contextlib.contextmanager
def replaced_when_done(dest: Path):
    """A temporary file beside ``dest``, renamed onto it when the block succeeds.

    The name is unique to this process and call (``.NAME.PID-RANDOM.part``), so two
    builds writing the same file at once each write their own and the last rename
    wins with a whole file; a failed block leaves ``dest`` as it was and no partial
    file behind.  The file is created by whoever writes it, so it gets the mode a plain
    ``open`` gives under the process's umask.

    Parameters
    ----------
    dest : Path
        The file to write.

    Yields
    ------
    Path
        Where to write it (not yet created).
    """
    dest = Path(dest)
    tmp = dest.with_name(f".{dest.name}.{os.getpid()}-{uuid.uuid4().hex[:8]}.part")
    try:
        yield tmp
        os.replace(tmp, dest)
    finally:
        tmp.unlink(missing_ok=True)
