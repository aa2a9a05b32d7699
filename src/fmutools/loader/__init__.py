"""Compile the C loader that lets C-only hosts run pythonfmu FMUs.

The loader (``loader.c``) is built with gcc for the Python that runs the build: the
paths of its shared libpython, its executable and its site-packages are baked in.
See ``docs/fmu-portability.md`` for what this means on another machine.

The loader depends only on that configuration, never on the FMU, so
:func:`cached_loader` compiles it once per configuration and keeps it in the
current user's private cache (:func:`fmutools.compiled.compiled_once`); every FMU gets
a copy of the same bytes.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import site
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

from fmutools.compiled import compiled_once, compiler_version

__all__ = ["LoaderError", "LoaderConfig", "loader_config", "compile_loader", "cached_loader",
           "REAL_BINARY_SUFFIX"]

SOURCE = Path(__file__).with_name("loader.c")

#: pythonfmu's binary is stored as ``binaries/linux64/<modelIdentifier><suffix>``; the
#: loader opens it under that name.
REAL_BINARY_SUFFIX = "_pythonfmu.so"

#: gcc flags of the loader (besides the include folder and the configuration header).
CFLAGS = ("-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-Wall")
LIBS = ("-ldl", "-lpthread")

# Loaders compiled or found in the cache by this process, by cache key.


class LoaderError(RuntimeError):
    """The C loader cannot be built for this Python."""


class LoaderConfig(dict):
    """Values baked into the loader (keys are the C macro names)."""


def loader_config() -> LoaderConfig:
    """Return the paths of this Python that the loader needs.

    Returns
    -------
    LoaderConfig
        ``FMUKIT_LIBPYTHON``, ``FMUKIT_EXECUTABLE``, ``FMUKIT_SITE_DIRS`` (joined by
        newlines) and ``FMUKIT_REAL_SUFFIX``.

    Raises
    ------
    LoaderError
        If this Python has no shared libpython.
    """
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        raise LoaderError(f"Python {sys.executable} is built without a shared libpython; "
                          "expected --enable-shared (or build with c_loader=False)")
    libdir = Path(sysconfig.get_config_var("LIBDIR"))
    name = sysconfig.get_config_var("INSTSONAME") or sysconfig.get_config_var("LDLIBRARY")
    lib = libdir / name
    if not lib.exists():
        raise LoaderError(f"shared libpython {lib} does not exist; expected the library "
                          f"of {sys.executable}")
    dirs = []
    for d in [*site.getsitepackages(), sysconfig.get_paths()["purelib"],
              sysconfig.get_paths()["platlib"]]:
        if d not in dirs and Path(d).is_dir():
            dirs.append(d)
    return LoaderConfig(
        FMUKIT_LIBPYTHON=str(lib),
        FMUKIT_EXECUTABLE=sys.executable,
        FMUKIT_SITE_DIRS="\n".join(dirs),
        FMUKIT_REAL_SUFFIX=REAL_BINARY_SUFFIX,
    )


def _toolchain() -> tuple[str, str]:
    """The C compiler and the folder of ``Python.h``; LoaderError if either is missing."""
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        raise LoaderError("no C compiler (gcc or cc) on PATH; install gcc to build FMUs "
                          "with the C loader")
    include = sysconfig.get_paths()["include"]
    if not (Path(include) / "Python.h").is_file():
        raise LoaderError(f"Python.h not found in {include}; install the Python development "
                          "headers")
    return cc, include


def compile_loader(out: str | Path, config: LoaderConfig | None = None) -> Path:
    """Compile ``loader.c`` into the shared library ``out``.

    Parameters
    ----------
    out : str or Path
        Path of the ``.so`` to write.
    config : LoaderConfig, optional
        Baked-in paths; default :func:`loader_config`.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    LoaderError
        If gcc or ``Python.h`` is missing or compilation fails.
    """
    out = Path(out)
    config = loader_config() if config is None else config
    cc, include = _toolchain()
    with tempfile.TemporaryDirectory(prefix="fmutools_loader_") as tmp:
        header = Path(tmp) / "loader_config.h"
        header.write_text("".join(f"#define {k} {json.dumps(v)}\n" for k, v in config.items()))
        cmd = [cc, *CFLAGS, f"-I{include}", "-include", str(header), str(SOURCE),
               "-o", str(out), *LIBS]
        proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise LoaderError(f"compiling the C loader failed: {proc.stderr.strip()}")
    return out


def _cache_key(config: LoaderConfig, cc: str, include: str) -> str:
    """Hash of everything the compiled loader depends on.

    The source, the baked-in configuration, the compiler (path and version), its flags
    and the Python ABI (version, SOABI, headers folder).
    """
    h = hashlib.sha256(SOURCE.read_bytes())
    h.update(json.dumps({
        "config": dict(config), "cc": cc, "cc_version": compiler_version(cc),
        "flags": [*CFLAGS, *LIBS], "include": include, "python": sys.version,
        "soabi": sysconfig.get_config_var("SOABI"),
    }, sort_keys=True).encode())
    return h.hexdigest()


def cached_loader(config: LoaderConfig | None = None) -> Path:
    """The loader for ``config``, compiled once and kept in the private cache.

    The cache entry ``loader-<key>.so`` is keyed by a hash of ``loader.c``, the
    configuration, the compiler and its flags, and the Python ABI.  It is compiled into
    a temporary folder and renamed into place, so a killed build never leaves half a
    library.  When the cache cannot be used, the loader is compiled into a temporary
    folder of this process instead.

    Parameters
    ----------
    config : LoaderConfig, optional
        Baked-in paths; default :func:`loader_config`.

    Returns
    -------
    Path
        The compiled library; copy it, never modify it.

    Raises
    ------
    LoaderError
        If gcc or ``Python.h`` is missing or compilation fails.
    """
    config = loader_config() if config is None else config
    cc, include = _toolchain()
    key = _cache_key(config, cc, include)
    return compiled_once("loader", key, lambda out: compile_loader(out, config))
