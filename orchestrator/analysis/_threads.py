"""Independent analyses on the cores of this machine, in threads of this process.

The heavy parts of a steady state or a sweep (BLAS products, LAPACK, the compiled
window kernel, numpy's element-wise loops) release the GIL, so two configurations run
side by side in two threads.  Each thread asks OpenBLAS for one thread of its own
(``openblas_set_num_threads_local``, OpenBLAS 0.3.27 and newer): N threads of
two-threaded products on N cores would fight over them.  Where that call is missing
(another BLAS, another OS), the threads run all the same.
"""

from __future__ import annotations

import ctypes
import functools
import os
from concurrent.futures import ThreadPoolExecutor

__all__ = ["map_threads", "one_blas_thread"]


@functools.cache
def _local_setters() -> tuple:
    """``openblas_set_num_threads_local`` of every OpenBLAS loaded in this process."""
    out = []
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as f:
            paths = {line.split()[-1] for line in f
                     if "openblas" in line.split()[-1].lower()}
    except OSError:
        return ()
    for path in sorted(paths):
        try:
            fn = ctypes.CDLL(path).openblas_set_num_threads_local
        except (OSError, AttributeError):
            continue
        fn.argtypes, fn.restype = [ctypes.c_int], ctypes.c_int
        out.append(fn)
    return tuple(out)


def one_blas_thread() -> None:
    """Ask every loaded OpenBLAS for one thread in the calling thread (a worker
    thread's initialiser)."""
    for setter in _local_setters():
        setter(1)


def map_threads(fn, items, workers: int | None = None) -> list:
    """``[fn(x) for x in items]``, the items in threads (one BLAS thread each).

    Parameters
    ----------
    fn : callable
        Thread-safe for distinct items.
    items : sequence
    workers : int, optional
        Threads (default: the cores, at most one per item); 1 runs in this thread.

    Returns
    -------
    list
        In the order of ``items``.
    """
    items = list(items)
    n = min(len(items), workers or os.cpu_count() or 1)
    if n <= 1:
        return [fn(x) for x in items]
    with ThreadPoolExecutor(n, initializer=one_blas_thread) as pool:
        return list(pool.map(fn, items))
