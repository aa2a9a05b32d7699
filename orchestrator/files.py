"""Files written whole or not at all, and file hashes: the one home for both.

Every result, metrics table, status file and archive the project writes goes through
:func:`atomic_write`: the content is written to a temporary file in the target folder
and renamed into place (``os.replace``), so a reader sees the old file or the new one,
never half of one, and an interrupted write leaves no partial file behind.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Callable

from fmutools.atomic import replaced_when_done


def atomic_write(path, writer: Callable[[str], None]) -> Path:
    """Write ``path`` through ``writer(tmp_name)`` and rename it into place.

    Parameters
    ----------
    path : path-like
        Final file; its folder is created if missing.
    writer : callable
        Called with the name of a temporary file in the same folder (not yet created,
        :func:`fmutools.atomic.replaced_when_done`); it writes the whole content there.
        If it raises, the temporary file is removed and the exception propagates,
        leaving ``path`` as it was.

    Returns
    -------
    Path
        ``path``, with the mode a plain ``open`` gives under the process's umask (not
        the private 0600 of a temporary file).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with replaced_when_done(path) as tmp:
        writer(str(tmp))
    return path


def write_text_atomic(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; returns ``path``.

    Parameters
    ----------
    path : path-like
        Final file; its folder is created if missing.
    text : str
        Whole content.

    Returns
    -------
    Path
        ``path``.
    """
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def write_json_atomic(path, data, **dumps) -> Path:
    """Write ``json.dumps(data, **dumps)`` to ``path`` atomically; returns ``path``.

    Parameters
    ----------
    path : path-like
        Final file; its folder is created if missing.
    data : object
        JSON-serialisable data.
    **dumps
        Keyword arguments of :func:`json.dumps` (e.g. ``indent``).

    Returns
    -------
    Path
        ``path``.
    """
    return write_text_atomic(path, json.dumps(data, **dumps))


def sha256_file(path, chunk: int = 1 << 20) -> str:
    """Hex SHA-256 of a file's bytes, read in chunks of ``chunk`` bytes.

    Parameters
    ----------
    path : path-like
        The file.
    chunk : int
        Read size (bytes); 1 MiB by default.

    Returns
    -------
    str
        64 hexadecimal digits.
    """
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(chunk), b""):
            h.update(block)
    return h.hexdigest()
