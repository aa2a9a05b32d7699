"""The structured engine's 2x2 pair products compiled to C (``pairs.c``), when a
compiler is.

A tick map of the structured engine (:mod:`orchestrator.analysis.structured`) carries
the structure's modes as 2x2 blocks; every product with it multiplies them, 99 times a
run for the rows and the columns of a Monte Carlo sample's loops.  numpy does it with
a temporary for every strided column; the compiled kernel takes one pass (the pairs
of the EOS loop's left product with isolation on, 93 rows: 19 against 61 us, the whole
product 180 against 225 us; with isolation off 10 against 26 us).  A left product
and an accumulated right one are the numpy expressions' values to the last bit
(``tests/orchestrator/test_pairs.py``); a right product that sets its rows is
``numpy.matmul``'s to its rounding.  The library is compiled once per configuration
into the private cache (:func:`fmutools.compiled.c_library`); without a C compiler, or
for arrays the kernel does not take (not float64, entries of a row not contiguous, an
output that is read-only or shares memory with the input), the numpy expressions run.
"""

from __future__ import annotations

import ctypes
import functools
from pathlib import Path

import numpy as np

from fmutools.compiled import c_library

__all__ = ["pair_left", "pair_right"]

SOURCE = Path(__file__).with_name("pairs.c")
CFLAGS = ("-std=c99", "-O2", "-fno-fast-math", "-ffp-contract=off", "-fPIC", "-shared",
          "-Wall")


@functools.cache
def _library() -> ctypes.CDLL | None:
    """``pairs.c`` compiled once, or None without a usable C compiler."""
    lib = c_library("pairs", SOURCE, CFLAGS)
    if lib is not None:
        ptr, n = ctypes.c_void_p, ctypes.c_long
        lib.pair_left.argtypes = [ptr, n, n, ptr, n, ptr, n]
        lib.pair_left.restype = None
        lib.pair_right.argtypes = [ptr, n, ptr, n, n, ptr, n, ctypes.c_int]
        lib.pair_right.restype = None
    return lib


def _rows(x: np.ndarray) -> bool:
    """True if ``x`` is a float64 matrix whose rows the kernel reads in place."""
    return (x.dtype == np.float64 and x.ndim == 2 and (x.strides[1] == 8 or x.shape[1] < 2)
            and x.strides[0] % 8 == 0 and x.strides[0] >= 0 and x.flags.aligned)


def _blocks(a: np.ndarray) -> bool:
    """True if ``a`` is a C-ordered float64 stack of 2x2 blocks."""
    return (a.dtype == np.float64 and a.ndim == 3 and a.shape[1:] == (2, 2)
            and a.flags.c_contiguous)


def pair_left(O: np.ndarray, a: np.ndarray, Y: np.ndarray) -> None:
    """``Y[:, :2n] += O[:, :2n] blockdiag(a)``, in place.

    Parameters
    ----------
    O : ndarray, shape (r, >= 2n)
        The rows multiplied.
    a : ndarray, shape (n, 2, 2)
        The pairs' blocks.
    Y : ndarray, shape (r, >= 2n)
        Added to (written in place).
    """
    n, r = a.shape[0], O.shape[0]
    lib = _library()
    if lib is not None and _rows(O) and _rows(Y) and Y.flags.writeable and _blocks(a) \
            and Y.shape[0] == r and min(O.shape[1], Y.shape[1]) >= 2 * n \
            and not np.may_share_memory(O, Y):
        lib.pair_left(O.ctypes.data, r, O.strides[0] // 8, a.ctypes.data, n,
                      Y.ctypes.data, Y.strides[0] // 8)
        return
    n_p = 2 * n
    q, v = O[:, 0:n_p:2], O[:, 1:n_p:2]
    Y[:, 0:n_p:2] += q * a[:, 0, 0] + v * a[:, 1, 0]
    Y[:, 1:n_p:2] += q * a[:, 0, 1] + v * a[:, 1, 1]


def pair_right(a: np.ndarray, X: np.ndarray, Y: np.ndarray, add: bool = False) -> None:
    """``Y[:2n] = blockdiag(a) X[:2n]`` (or ``+=`` with ``add``), in place.

    Parameters
    ----------
    a : ndarray, shape (n, 2, 2)
        The pairs' blocks.
    X : ndarray, shape (>= 2n, c)
        The columns multiplied.
    Y : ndarray, shape (>= 2n, c)
        Written (or added to) in place.
    add : bool
        Add to ``Y`` rather than set it.
    """
    n, c = a.shape[0], X.shape[1]
    lib = _library()
    if lib is not None and _rows(X) and _rows(Y) and Y.flags.writeable and _blocks(a) \
            and Y.shape[1] == c and min(X.shape[0], Y.shape[0]) >= 2 * n \
            and not np.may_share_memory(X, Y):
        lib.pair_right(a.ctypes.data, n, X.ctypes.data, c, X.strides[0] // 8,
                       Y.ctypes.data, Y.strides[0] // 8, int(add))
        return
    n_p = 2 * n
    if add:
        q, v = X[0:n_p:2], X[1:n_p:2]
        Y[0:n_p:2] += a[:, 0, 0, None] * q + a[:, 0, 1, None] * v
        Y[1:n_p:2] += a[:, 1, 0, None] * q + a[:, 1, 1, None] * v
    else:
        np.matmul(a, X[:n_p].reshape(n, 2, c), out=Y[:n_p].reshape(n, 2, c))
