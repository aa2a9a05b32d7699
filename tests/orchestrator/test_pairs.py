"""The structured engine's compiled 2x2 pair products (orchestrator/analysis/pairs.c)
against the numpy expressions they replace: the same bits where the order of the
operations is the same (a left product, an accumulated right one), ``numpy.matmul``'s
value to its rounding where it is not, and the numpy way when there is no compiler or
the arrays are not laid out for the kernel."""

import shutil

import numpy as np
import pytest

from orchestrator.analysis import _pairs
from orchestrator.analysis.fastparts import _BlockPower
from orchestrator.analysis.structured import _Form


def _numpy_left(O, a, Y):
    n_p = 2 * a.shape[0]
    Y = Y.copy()
    q, v = O[:, 0:n_p:2], O[:, 1:n_p:2]
    Y[:, 0:n_p:2] += q * a[:, 0, 0] + v * a[:, 1, 0]
    Y[:, 1:n_p:2] += q * a[:, 0, 1] + v * a[:, 1, 1]
    return Y


def _numpy_right_add(a, X, Y):
    n_p = 2 * a.shape[0]
    Y = Y.copy()
    q, v = X[0:n_p:2], X[1:n_p:2]
    Y[0:n_p:2] += a[:, 0, 0, None] * q + a[:, 0, 1, None] * v
    Y[1:n_p:2] += a[:, 1, 0, None] * q + a[:, 1, 1, None] * v
    return Y


def _data(rng, r, s, n):
    # scales spread as a loop's are (1e-16 to 3e11): a wrong order of operations or a
    # fused multiply-add shows in the last bits
    scale = 10.0 ** rng.uniform(-8, 8, size=s)
    O = rng.standard_normal((r, s)) * scale
    a = rng.standard_normal((n, 2, 2)) * 10.0 ** rng.uniform(-3, 3, size=(n, 1, 1))
    Y = rng.standard_normal((r, s)) * scale
    return O, a, Y


def test_the_kernel_is_compiled_where_there_is_a_compiler():
    if shutil.which("gcc") is None and shutil.which("cc") is None:
        pytest.skip("no C compiler on this machine: only the numpy way can run here")
    assert _pairs._library() is not None


@pytest.mark.parametrize("r, s, n", [(93, 404, 139), (33, 293, 139), (1, 6, 3), (0, 4, 2)])
def test_left_product_is_the_numpy_expression_bit_for_bit(r, s, n):
    rng = np.random.default_rng(r + s)
    O, a, Y = _data(rng, r, s, n)
    want = _numpy_left(O, a, Y)
    got = Y.copy()
    _pairs.pair_left(O, a, got)
    assert np.array_equal(got, want)
    # rows of a larger array (a run's row Krylov products O[q]), written into a view
    big = np.zeros((3, r, s + 5))
    big[1, :, :s] = O
    out = np.zeros((r, s + 7))
    out[:, :s] = Y
    _pairs.pair_left(big[1], a, out[:, :s + 7])
    assert np.array_equal(out[:, :s], want)
    assert not out[:, s:].any()


@pytest.mark.parametrize("c", [12, 17, 32, 1, 0])
def test_right_product_accumulated_bit_for_bit_and_set_to_matmul_rounding(c):
    rng = np.random.default_rng(c)
    n, s = 139, 293
    X = rng.standard_normal((s, c)) * 10.0 ** rng.uniform(-8, 8, size=(s, 1))
    a = rng.standard_normal((n, 2, 2))
    Y = rng.standard_normal((s, c))
    got = Y.copy()
    _pairs.pair_right(a, X, got, add=True)
    assert np.array_equal(got, _numpy_right_add(a, X, Y))
    got = np.full((s, c), np.nan)
    _pairs.pair_right(a, X, got)
    want = np.matmul(a, X[:2 * n].reshape(n, 2, c)).reshape(2 * n, c)
    # two products and a sum: each entry within a few roundings of its terms' sizes
    size = np.abs(a).reshape(n, 2, 2) @ np.abs(X[:2 * n]).reshape(n, 2, c)
    assert np.all(np.abs(got[:2 * n] - want) <= 4 * np.finfo(float).eps * size.reshape(2 * n, c))
    assert np.isnan(got[2 * n:]).all()   # the other rows are the caller's


def test_without_a_compiler_or_with_strided_arrays_the_numpy_way_gives_the_same(monkeypatch):
    rng = np.random.default_rng(7)
    O, a, Y = _data(rng, 21, 300, 139)
    want = _numpy_left(O, a, Y)
    X = rng.standard_normal((300, 9))
    want_r = np.matmul(a, X[:278].reshape(-1, 2, 9)).reshape(278, 9)
    Yr = rng.standard_normal((300, 9))
    want_add = _numpy_right_add(a, X, Yr)
    for case in ("transposed", "no compiler"):
        if case == "no compiler":
            monkeypatch.setattr(_pairs, "_library", lambda: None)
            O2, Y2, X2 = O, Y.copy(), X
        else:   # entries of a row not contiguous: the kernel does not take them
            O2 = np.asfortranarray(O)
            Y2 = np.asfortranarray(Y.copy())
            X2 = np.asfortranarray(X)
            assert not _pairs._rows(O2)
        _pairs.pair_left(O2, a, Y2)
        assert np.array_equal(Y2, want)
        out = np.empty((300, 9))
        _pairs.pair_right(a, X2, out)
        assert np.array_equal(out[:278], want_r)
        acc = Yr.copy() if case == "no compiler" else np.asfortranarray(Yr.copy())
        _pairs.pair_right(a, X2, acc, add=True)
        assert np.array_equal(acc, want_add)


def test_a_tick_form_and_a_block_power_multiply_as_their_matrices():
    """The two users of the kernel, against their dense matrices (independent: a
    product of numpy matrices)."""
    rng = np.random.default_rng(3)
    n, k_in, rest, s = 40, 3, 7, 87
    a = rng.standard_normal((n, 2, 2)) * 0.5
    gamma = rng.standard_normal((2 * n, k_in))
    W = rng.standard_normal((k_in + rest, s))
    W[:, :2 * n][rng.random((k_in + rest, 2 * n)) < 0.5] = 0.0
    form = _Form(a, gamma, W, np.zeros((s, 1)))
    M = form.dense()
    X = rng.standard_normal((s, 5))
    O = rng.standard_normal((6, s))
    tol = 1e-13 * np.abs(M).max() * max(np.abs(X).max(), np.abs(O).max())
    assert np.abs(form.right(X) - M @ X).max() <= tol
    assert np.abs(form.left(O) - O @ M).max() <= tol
    # a block power whose pairs lead (the kernel) and one whose pairs do not (numpy)
    P = rng.standard_normal((n, 2, 2))
    cols = np.arange(2 * n, s)
    Xc = rng.standard_normal((s, cols.size))
    for at in (2 * np.arange(n), 2 * np.arange(n)[::-1]):
        bp = _BlockPower(s, at, P, cols, Xc)
        dense = np.zeros((s, s))
        dense[:, cols] = Xc
        for j, i in enumerate(at):
            dense[i:i + 2, i:i + 2] += P[j]
        assert np.abs(bp @ X - dense @ X).max() <= 1e-13 * np.abs(dense).max() * np.abs(X).max() * s
