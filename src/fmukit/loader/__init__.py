"""Compile the C loader that lets C-only hosts run pythonfmu FMUs.

The loader (``loader.c``) is built with gcc for the Python that runs the build: the
paths of its shared libpython, its executable and its site-packages are baked in.
See ``docs/fmu-portability.md`` for what this means on another machine.
"""

from __future__ import annotations

import json
import shutil
import site
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

__all__ = ["LoaderError", "LoaderConfig", "loader_config", "compile_loader"]

SOURCE = Path(__file__).with_name("loader.c")


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
    from fmukit.build import REAL_BINARY_SUFFIX

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
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        raise LoaderError("no C compiler (gcc or cc) on PATH; install gcc to build FMUs "
                          "with the C loader")
    include = sysconfig.get_paths()["include"]
    if not (Path(include) / "Python.h").is_file():
        raise LoaderError(f"Python.h not found in {include}; install the Python development "
                          "headers")
    with tempfile.TemporaryDirectory(prefix="fmukit_loader_") as tmp:
        header = Path(tmp) / "loader_config.h"
        header.write_text("".join(f"#define {k} {json.dumps(v)}\n" for k, v in config.items()))
        cmd = [cc, "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-Wall",
               f"-I{include}", "-include", str(header), str(SOURCE), "-o", str(out),
               "-ldl", "-lpthread"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise LoaderError(f"compiling the C loader failed: {proc.stderr.strip()}")
    return out
