"""Shared measuring of the benchmarks that run each case in a fresh process.

A benchmark re-runs its own script with ``--worker ...``; the worker measures CPU time
and peak memory of its process and prints one marked JSON line (:func:`emit`), which
:func:`run_worker` reads back.
"""

from __future__ import annotations

import ctypes
import json
import os
import resource
import subprocess
import sys
import time

MARK = "@@RESULT@@"
_BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def peak_rss_mb() -> float:
    """Peak resident memory of this process (MB)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # pragma: no cover


def blas_cores() -> list:
    """The kernel family each OpenBLAS loaded in this process runs (``Haswell``,
    ``SkylakeX``, ...): what a measured product rate depends on.  ``OPENBLAS_CORETYPE``
    chooses it when the library's own detection picks less than the CPU can do."""
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as f:
            paths = sorted({ln.split()[-1] for ln in f if "openblas" in ln.split()[-1].lower()})
    except OSError:
        return []
    out = []
    for path in paths:
        lib = ctypes.CDLL(path)
        for name in ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename",
                     "openblas_get_corename64_", "openblas_get_corename"):
            fn = getattr(lib, name, None)
            if fn is not None:
                fn.restype = ctypes.c_char_p
                out.append(fn().decode())
                break
    return out


def blas_choice() -> str:
    """The kernels this process's OpenBLAS runs and who chose them: the library's own
    detection, or ``OPENBLAS_CORETYPE`` (then also what the library alone picks on this
    CPU, from a fresh interpreter without the variable)."""
    cores = ", ".join(blas_cores()) or "unknown"
    forced = os.environ.get("OPENBLAS_CORETYPE")
    if not forced:
        return f"{cores} (the library's detection)"
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    code = (f"import sys; sys.path.insert(0, {os.path.dirname(__file__)!r}); import numpy; "
            "from _measure import blas_cores; print(', '.join(blas_cores()))")
    try:
        alone = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                               text=True, timeout=60, check=False).stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        alone = "unknown"
    return f"{cores} (set by OPENBLAS_CORETYPE={forced}; the library alone picks {alone})"


def best_of(fn, repeat: int) -> tuple:
    """``(seconds, result)``: the shortest of ``repeat`` timed calls of ``fn`` and the
    last call's result."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def cpu_s() -> float:
    """User + system CPU time of this process (s)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def emit(result: dict) -> None:
    """Print a worker's result for :func:`run_worker`."""
    print(MARK + json.dumps(result))


def run_worker(script: str, args: list, case: str, threads: int | None = None) -> dict:
    """Run ``script --worker ARGS`` in a fresh process; its :func:`emit`-ted result.

    ``threads`` sets the BLAS threads of the worker (default: the library's own).
    """
    env = dict(os.environ)
    if threads is not None:
        for var in _BLAS_THREADS:
            env[var] = str(threads)
    proc = subprocess.run([sys.executable, script, *args], capture_output=True, text=True,
                          env=env)
    if proc.returncode != 0:
        raise RuntimeError(f"benchmark case {case!r} failed:\n{proc.stderr[-3000:]}")
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith(MARK)][-1]
    return json.loads(line[len(MARK):])
