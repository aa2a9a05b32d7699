"""C libraries compiled once per configuration and kept in the private cache.

The C loader of the Python FMUs (:mod:`fmutools.loader`) and the master's compiled tick
loop (:mod:`orchestrator.cosim.fastloop`) are both built this way: the cache entry
``<name>-<key>.so`` is keyed by a hash of everything the library depends on, compiled
into a temporary folder and renamed into place (a killed build never leaves half a
library), and used only if it is a regular file of the current user that neither its
group nor others can write (anything else is compiled again and replaced).  When the
cache cannot be used, the library is compiled into a temporary folder of this process,
removed when the process exits.
"""

from __future__ import annotations

import atexit
import ctypes
import functools
import hashlib
import json
import os
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from pathlib import Path

from fmutools.fmucache import CacheError, cache_root, is_own

__all__ = ["c_library", "compiled_once", "compiler_version", "is_own_file"]

_COMPILED: dict[str, Path] = {}


@functools.cache
def compiler_version(cc: str) -> str:
    """What ``cc --version`` prints (asked once per process)."""
    return subprocess.run([cc, "--version"], capture_output=True, text=True,
                          check=False).stdout


def is_own_file(path: Path) -> bool:
    """True if ``path`` is a non-empty regular file (not a link) of the current user
    that neither its group nor others can write (:func:`fmutools.fmucache.is_own`)."""
    try:
        return is_own(path) and os.lstat(path).st_size > 0
    except OSError:
        return False


@functools.cache
def _process_folder() -> Path:
    """A private temporary folder of this process, removed when the process exits."""
    folder = Path(tempfile.mkdtemp(prefix="fmutools_compiled_"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    return folder


def compiled_once(name: str, key: str, compile_to: Callable[[Path], object]) -> Path:
    """The library ``<name>-<key>.so``, compiled by ``compile_to`` the first time.

    Parameters
    ----------
    name : str
        File name prefix, e.g. ``"loader"``.
    key : str
        Hash of everything the library depends on (source, configuration, compiler,
        flags).
    compile_to : callable
        ``compile_to(path)`` writes the library to ``path`` or raises.

    Returns
    -------
    Path
        The cached library; copy or load it, never modify it.
    """
    known = _COMPILED.get(f"{name}-{key}")
    if known is not None and is_own_file(known):
        return known
    try:
        root = cache_root()
    except CacheError:
        root = _process_folder()
    dest = root / f"{name}-{key}.so"
    if not is_own_file(dest):
        partial = Path(tempfile.mkdtemp(prefix=f".{name}-partial-", dir=root))
        try:
            out = partial / f"{name}.so"
            compile_to(out)
            os.chmod(out, 0o755)  # whatever the umask: no one else may write it
            os.replace(out, dest)
        finally:
            shutil.rmtree(partial, ignore_errors=True)
    _COMPILED[f"{name}-{key}"] = dest
    return dest


def c_library(name: str, source: Path, flags, libs=()):
    """The C file ``source`` compiled once per configuration and loaded, or None.

    The cache entry ``<name>-<key>.so`` (:func:`compiled_once`) is keyed by a hash of
    the source, the compiler (path and version) and its flags.

    Parameters
    ----------
    name : str
        File name prefix of the cache entry.
    source : Path
        The one C file.
    flags, libs : sequence of str
        Compiler flags (``-shared`` among them) and the libraries to link after it.

    Returns
    -------
    ctypes.CDLL or None
        None without a C compiler or when it fails: the caller's other way runs.
    """
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        return None
    h = hashlib.sha256(Path(source).read_bytes())
    h.update(json.dumps({"cc": cc, "cc_version": compiler_version(cc),
                         "flags": [*flags, *libs]}, sort_keys=True).encode())

    def compile_to(out):
        proc = subprocess.run([cc, *flags, str(source), "-o", str(out), *libs],
                              capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            raise OSError(proc.stderr.strip())

    try:
        return ctypes.CDLL(str(compiled_once(name, h.hexdigest(), compile_to)))
    except OSError:
        return None
