"""Independent analyses on the cores of this machine, in threads of this process.

The heavy parts of a steady state or a sweep (BLAS products, LAPACK, the compiled
window kernel, numpy's element-wise loops) release the GIL, so two configurations run
side by side in two threads.  Each thread asks OpenBLAS for one thread of its own
(``openblas_set_num_threads_local``, OpenBLAS 0.3.27 and newer): N threads of
two-threaded products on N cores would fight over them.  Where that call is missing
(another BLAS, another OS), the threads run all the same.

The "local" count is not the worker's alone: after a worker thread has set it, the
process's other threads compute with it too (measured with the OpenBLAS numpy and scipy
ship).  A pool of such workers (:func:`map_threads`, the linear engine's cases) runs
inside :func:`blas_threads_kept`, which gives the process its count back: without it,
every later product of the process ran on one thread, and the exponential an FMU build
packs (the stiff Ritz block's) moved in its last bits, so that an FMU built after a
linear campaign differed from one built before.
"""

from __future__ import annotations

import ctypes
import functools
import os
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

__all__ = ["blas_pool", "blas_thread_counts", "blas_threads_kept", "map_threads", "one_blas_thread"]


# the thread-count query under the names OpenBLAS builds export (plain, and the
# prefixed and 64-bit-integer builds numpy and scipy ship)
_GETTERS = ("openblas_get_num_threads", "scipy_openblas_get_num_threads64_",
            "scipy_openblas_get_num_threads")


@functools.cache
def _openblas() -> tuple:
    """``(openblas_set_num_threads_local, its thread-count query or None)`` of every
    OpenBLAS loaded in this process that has the setter."""
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as f:
            paths = {line.split()[-1] for line in f
                     if "openblas" in line.split()[-1].lower()}
    except OSError:
        return ()
    out = []
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
            setter = lib.openblas_set_num_threads_local
        except (OSError, AttributeError):
            continue
        setter.argtypes, setter.restype = [ctypes.c_int], ctypes.c_int
        getter = next((getattr(lib, n) for n in _GETTERS if hasattr(lib, n)), None)
        if getter is not None:
            getter.argtypes, getter.restype = [], ctypes.c_int
        out.append((setter, getter))
    return tuple(out)


def _local_setters() -> tuple:
    """``openblas_set_num_threads_local`` of every OpenBLAS loaded in this process."""
    return tuple(setter for setter, _ in _openblas())


def one_blas_thread() -> None:
    """Ask every loaded OpenBLAS for one thread in the calling thread (a worker
    thread's initialiser)."""
    for setter in _local_setters():
        setter(1)


def blas_thread_counts() -> list:
    """The thread count every loaded OpenBLAS uses for the calling thread (empty where
    the call is missing)."""
    getters = [getter for _, getter in _openblas()]
    if None not in getters:   # read, not set: another thread may compute meanwhile
        return [fn() for fn in getters]
    setters = _local_setters()
    counts = [fn(1) for fn in setters]   # the call returns the count it replaces
    for fn, n in zip(setters, counts):
        fn(n)
    return counts


@contextmanager
def blas_threads_kept():
    """Give every loaded OpenBLAS the calling thread's count back when the block ends
    (the block's worker threads may take one each: :func:`one_blas_thread`)."""
    before = blas_thread_counts()
    try:
        yield
    finally:
        for fn, n in zip(_local_setters(), before):
            fn(n)


@contextmanager
def blas_pool(workers: int):
    """A pool of ``workers`` threads of one BLAS thread each, the calling thread's count
    given back when the pool closes (a worker's one thread leaks into the process:
    :func:`blas_threads_kept`).

    Parameters
    ----------
    workers : int
        Threads of the pool.

    Yields
    ------
    concurrent.futures.ThreadPoolExecutor
    """
    with blas_threads_kept(), ThreadPoolExecutor(workers, initializer=one_blas_thread) as pool:
        yield pool


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
    with blas_pool(n) as pool:
        return list(pool.map(fn, items))
