"""Parts of the fast path (:mod:`orchestrator.analysis.fast`) that stand alone: the record
it returns, the memory-state pruning, the causal FFT convolution of its runs and the
powers by squaring of their maps."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft

from ._pairs import pair_right
from .blocks import AnalysisError

__all__ = ["NonlinearError", "Record"]


class NonlinearError(AnalysisError):
    """A record leaves the linear model: a rail or limit of an FMU is reached."""


@dataclass(frozen=True)
class _RunType:
    """Matrices of a run of ``L`` ticks with one map (memory state ``s``, ``r`` rows).

    The input side is per source channel and built on first use (:meth:`FastResponse.
    _columns`): a record driven by a few channels pays the Krylov products of those
    only."""

    L: int
    ML: np.ndarray      # (s, s)       M^L
    O: np.ndarray       # (L * r_live, s)  C M^q, the rows that are not zero by structure
    live: np.ndarray    # (r_live,)    those rows (e.g. a loop at gain 0 leaves its own out)
    M: np.ndarray       # (s, s)       the tick map
    N: np.ndarray       # (s, m)       its input columns
    D: np.ndarray       # (r_live, m)  feedthrough of the live rows
    cols: dict          # channel -> (M^(L-1-l) N_c (s, L), Markov parameters (L, r_live))
    powers: tuple = ()  # M^(2^j) for 2^j < L: the doubling steps of the Krylov products


@dataclass(frozen=True)
class Record:
    """A fast-path record; unpacks as ``values, times``.

    Attributes
    ----------
    values : ndarray, shape (n_ticks + 1, n_refs)
        Each reference at every tick (as the master records it: after the tick's inputs
        are set, before it steps).
    times : ndarray, shape (n_ticks + 1,)
        Tick times (s), exact.
    refs : tuple of str
        The columns, ``instance.variable``.
    limits : dict of str to float
        Per checked output, the largest fraction of its allowed range used (1 = at the
        rail).
    reached : tuple of str
        The checked outputs that left their range (a record run with ``check=False``).
    bounded : tuple of str
        The checked outputs (and limits inside steps) whose ``limits`` entry is an upper
        bound of the fraction used, not the fraction itself: a bound kept them inside
        their range, so they were not computed (``run_many(..., bound_limits=True)``).
    """

    values: np.ndarray
    times: np.ndarray
    refs: tuple
    limits: dict
    reached: tuple = ()
    bounded: tuple = ()

    def __iter__(self):
        return iter((self.values, self.times))

    def column(self, ref: str) -> np.ndarray:
        """The record of ``ref``."""
        return self.values[:, self.refs.index(ref)]


def _relevant(maps: dict, rows) -> np.ndarray:
    """States (of the lifted state) a record can need: driven by a source from rest and
    seen by a computed row, through the structural non-zeros of the tick maps.

    A state no source reaches stays exactly zero from rest; one that no computed row
    depends on, however many ticks later, changes nothing computed.  Both are exact
    zeros of the products, dropped (a controller at gain 0 and the piezo behind it
    when nothing checks them; 430 -> 311 states for the EOS loop with isolation off).

    Parameters
    ----------
    maps : dict of signature to (M, N)
        Every kind of tick's map ``X+ = M X + N w``.
    rows : sequence of int
        Lifted-state rows the records compute.

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    dep = np.zeros(next(iter(maps.values()))[0].shape, bool)    # dep[i, j]: i+ reads j
    reach = np.zeros(dep.shape[0], bool)
    for M, N in maps.values():
        dep |= M != 0.0
        reach |= np.any(N != 0.0, axis=1)
    need = np.any(dep[np.asarray(rows, int)], axis=0)
    while True:   # forward from the sources, backward from the rows: fixed points
        more_reach = reach | np.any(dep[:, reach], axis=1)
        more_need = need | np.any(dep[need], axis=0)
        if (more_reach == reach).all() and (more_need == need).all():
            return reach & need
        reach, need = more_reach, more_need


def _inner_used(G: np.ndarray, Y: np.ndarray, lo: float, hi: float) -> tuple:
    """A limit inside a step: the values ``G @ y`` at every sub-step of each step from
    the rows ``Y`` (n_steps, k) of its start state and held inputs.

    Returns
    -------
    used : float
        The largest fraction of the allowed range used.
    step : int
        The first step that leaves ``[lo, hi]``, -1 if none.
    value : float
        The value there (0.0 if none).
    """
    # the extremes of all values first, from the sub-steps that can hold them (the
    # vertices of the hull of G's rows: for an amplifier's first-order sub-steps, the
    # two ends of a segment); where they come within 1e-9 of the range, from every
    # sub-step, and the steps themselves only where a value leaves the range
    ext = _extreme_rows(G)
    if ext.size < G.shape[0]:
        V = Y @ G[ext].T
        top_all, bottom_all = V.max(), V.min()
        margin = 1e-9 * max([abs(v) for v in (lo, hi) if math.isfinite(v)], default=0.0)
        if top_all < hi - margin and bottom_all > lo + margin:   # False for NaN
            return float(max(top_all / hi if hi > 0 else 0.0,
                             bottom_all / lo if lo < 0 else 0.0)), -1, 0.0
    top_all, bottom_all = -np.inf, np.inf
    for a in range(0, Y.shape[0], 4096):   # (ticks, sub-steps) in slices
        V = Y[a:a + 4096] @ G.T
        top_all, bottom_all = max(top_all, V.max()), min(bottom_all, V.min())
    used = max(top_all / hi if hi > 0 else 0.0, bottom_all / lo if lo < 0 else 0.0)
    if not (top_all > hi or bottom_all < lo):   # NaN: compared per step below
        if not (np.isnan(top_all) or np.isnan(bottom_all)):
            return float(used), -1, 0.0
    top, bottom = np.full(Y.shape[0], -np.inf), np.full(Y.shape[0], np.inf)
    for a in range(0, Y.shape[0], 4096):
        V = Y[a:a + 4096] @ G.T
        top[a:a + 4096], bottom[a:a + 4096] = V.max(axis=1), V.min(axis=1)
    bad = np.flatnonzero((top > hi) | (bottom < lo))
    if not bad.size:
        return float(used), -1, 0.0
    k = int(bad[0])
    return float(used), k, float(top[k] if top[k] > hi else bottom[k])


# the rows of a sub-step matrix that hold its extremes, per matrix (kept with it, so
# that its id stays its own)
_EXTREME: dict = {}


def _extreme_rows(G: np.ndarray) -> np.ndarray:
    """The rows of ``G`` on which ``max_j g_j . y`` and ``min_j g_j . y`` are attained
    for every ``y``: the vertices of the convex hull of its rows (every row where the
    hull is not found), kept per matrix."""
    hit = _EXTREME.get(id(G))
    if hit is not None and hit[0] is G:
        return hit[1]
    rows = np.arange(G.shape[0])
    if G.shape[0] > 2 and np.isfinite(G).all():
        P = G - G.mean(axis=0)
        _, sv, Vt = np.linalg.svd(P, full_matrices=False)
        d = int(np.sum(sv > sv[0] * max(G.shape) * np.finfo(float).eps)) if sv[0] else 0
        P = P @ Vt[:d].T
        if d == 0:
            rows = rows[:1]
        elif d == 1:
            rows = np.unique([np.argmin(P[:, 0]), np.argmax(P[:, 0])])
        elif d < G.shape[0] - 1:
            from scipy.spatial import ConvexHull, QhullError
            try:
                rows = np.sort(ConvexHull(P).vertices)
            except (QhullError, ValueError):
                pass
    if len(_EXTREME) > 256:
        _EXTREME.clear()
    _EXTREME[id(G)] = (G, rows)
    return rows


def _inner_basis(lin, r0: int) -> tuple:
    """The rows limits inside a step read, and those limits: ``(basis, inner)``.

    ``basis`` the lifted-state rows, from row ``r0`` of the recorded rows on: per block
    with such limits, its state and the inputs some sub-step row reads (a column of
    zeros in every one of its sub-step matrices, a stack's elongation into its
    amplifier's rails and current, is left out: a row no limit needs costs its row
    Krylov products in every run type).  ``inner`` one ``(name, G, lo, hi, what, cols,
    n_state, period)`` per limit, ``G`` on the columns kept (the same array for the same
    block, so that what is kept per matrix stays kept)."""
    basis, inner = [], []
    for n, b in lin.blocks.items():
        if not b.inner:
            continue
        sx, su, _ = lin.slots[n]
        used = np.any(np.vstack([G for _, G, *_ in b.inner]) != 0.0, axis=0)
        keep = np.concatenate([np.arange(b.n), b.n + np.flatnonzero(used[b.n:])])
        cols = r0 + len(basis) + np.arange(keep.size)
        rows = [*range(sx.start, sx.stop), *range(su.start, su.stop)]
        basis += [rows[i] for i in keep]
        inner += [(f"{n}.{o}", _kept_columns(G, keep), lo, hi, what, cols, b.n, b.period)
                  for o, G, lo, hi, what in b.inner]
    return basis, inner


# a sub-step matrix on the columns its block's limits read, per matrix (by id, with it)
_COLUMNS: dict = {}


def _kept_columns(G: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``G[:, keep]``, ``G`` itself when every column is kept; the same array for the
    same ``G`` (its extreme rows, :func:`_extreme_rows`, are kept by id)."""
    if keep.size == G.shape[1]:
        return G
    hit = _COLUMNS.get(id(G))
    if hit is None or hit[0] is not G or not np.array_equal(hit[1], keep):
        if len(_COLUMNS) > 256:
            _COLUMNS.clear()
        hit = _COLUMNS[id(G)] = (G, keep, np.ascontiguousarray(G[:, keep]))
    return hit[2]


def _inner_checks(inner, Y, at, bounds, limits: dict, reached: list, times, check: bool,
                  bound: bool, bounded: list):
    """The limits inside a step of a record's rows ``Y`` (see `FastResponse._record`):
    ``limits`` and ``reached`` updated; with ``check``, the first one reached raises
    :class:`NonlinearError`.  The step of a block due at tick ``k`` starts from its state
    after tick ``k - 1`` (at rest before tick 0) with its inputs held from tick ``k``.
    With ``bound``, a limit that the rows' largest values keep inside its range
    (:func:`_inner_bound`, every sub-step of every step at once) is not evaluated sub-step
    by sub-step: ``limits`` holds that bound, an upper bound of the fraction used, and
    its name is appended to ``bounded``."""
    for ref, G, lo, hi, what, c, nx, period in inner:
        if bounds is not None and not np.isnan(bounds[c]).any():   # bounded, not computed
            limits[ref] = max(limits[ref], _inner_bound(G, bounds[c]) / min(hi, -lo))
            bounded.append(ref)
            continue
        Yc = Y[:, c if at is None else at[c]]
        if bound and hi > 0 and lo < 0:   # the start states are rows of Yc too
            b = _inner_bound(G, np.abs(Yc).max(axis=0))
            if b * (1.0 + 1e-6) < min(hi, -lo):   # NaN or inf: not cleared
                limits[ref] = max(limits.get(ref, 0.0), b / min(hi, -lo))
                bounded.append(ref)
                continue
        start = np.vstack([np.zeros((1, nx)), Yc[:-1, :nx]])
        used, k, v = _inner_used(G, np.hstack([start, Yc[:, nx:]])[::period], lo, hi)
        limits[ref] = max(limits.get(ref, 0.0), used)
        if k < 0:
            continue
        if ref not in reached:
            reached.append(ref)
        if check:
            raise NonlinearError(
                f"{ref} reaches its {what} inside the step from t = {times[k * period]:.6g} "
                f"s ({v:.4g} at an internal sub-step, outside [{lo:.4g}, {hi:.4g}]), where "
                "the FMU leaves the linear model: run this case with the co-simulation "
                "(--engine cosim)")


def _add_forced(out: np.ndarray, Wu: np.ndarray, forced, t, active, sel) -> None:
    """``out += forced(t, active, Wu, sel)`` (see `FastResponse._forced`) for the runs
    whose inputs ``Wu`` (n_u, L, k) are not all zero: the others' forced response is
    zero, and an event's source is quiet in most runs of a record (467 of the EOS
    budget's 840 late runs carry input)."""
    live = np.flatnonzero(Wu.reshape(Wu.shape[0], -1).any(axis=1))
    if live.size == Wu.shape[0]:
        out += forced(t, active, Wu, sel)
    elif live.size:
        out[live] += forced(t, active, Wu[live], sel)


def _run_views(Y: np.ndarray, win: np.ndarray, whole: bool):
    """Per record, the rows of ``Y`` (E, K, c) that the runs ``win`` (n_u, L) fill, as
    writable views ``(E, n_u, L c)``; None unless ``whole`` (the runs fill every column)
    and the runs start evenly spaced, at least ``L`` apart (a run type's runs do)."""
    n_u, L = win.shape
    step = int(win[1, 0] - win[0, 0]) if n_u > 1 else L
    if not whole or n_u == 0 or step < L or not np.array_equal(
            win, win[0, 0] + step * np.arange(n_u)[:, None] + np.arange(L)):
        return None
    E, _, c = Y.shape
    z = Y.itemsize
    if Y.strides != (Y.shape[1] * c * z, c * z, z):
        return None
    return np.lib.stride_tricks.as_strided(Y[:, win[0, 0]:], (E, n_u, L * c),
                                           (Y.strides[0], step * c * z, z))


def _inner_bound(G: np.ndarray, b: np.ndarray):
    """Upper bound of ``|G @ y|`` over the sub-steps from bounds ``b`` of ``|y|``: one
    number for ``b`` (n,), one per column for ``b`` (n, E) (every record at once)."""
    return (np.abs(G) @ b).max(axis=0)


def _causal_conv(Hf: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``y[u, q] = sum_{l <= q} h[q - l] w[u, l]`` for every run ``u``, by FFT.

    Parameters
    ----------
    Hf : ndarray, shape (n_f, r, m)
        ``rfft`` of ``h`` (L, r, m) at length ``_fft_length(L)``.
    w : ndarray, shape (n_u, L, m)

    Returns
    -------
    ndarray, shape (n_u, L, r)
    """
    L = w.shape[1]
    n = _fft_length(L)
    # one thread: campaign cases and Monte Carlo samples already run one per core
    Wf = sfft.rfft(w, n, axis=1)                    # (u, f, m)
    if Wf.shape[2] == 1:
        Yf = Wf * Hf[None, :, :, 0]
    else:
        Yf = np.einsum("frm,ufm->ufr", Hf, Wf, optimize=True)
    return sfft.irfft(Yf, n, axis=1)[:, :L]


def _fft_length(L: int) -> int:
    """A fast FFT length for a linear convolution of two ``L``-long sequences."""
    return sfft.next_fast_len(2 * L - 1, real=True)


def _powers(M: np.ndarray, L: int) -> tuple:
    """``M^(2^j)`` for every ``2^j < L`` (by squaring): the doubling steps of a run's
    Krylov products and the binary digits of its ``M^L``."""
    out = []
    if L > 1:
        out.append(M)
        while (1 << len(out)) < L:
            out.append(out[-1] @ out[-1])
    return tuple(out)


def _doubling(L: int) -> list:
    """``(lo, hi)`` of each doubling step of a run of ``L`` ticks: step ``j`` gives the
    Krylov products ``q`` in ``[lo, hi) = [2^j, min(2^(j+1), L))`` from those in
    ``[0, hi - lo)`` and ``M^(2^j)``."""
    return [(1 << j, min(2 << j, L)) for j in range((L - 1).bit_length())]


def _power(M: np.ndarray, L: int, powers: tuple) -> np.ndarray:
    """``M^L`` from ``powers = _powers(M, L)``, by the binary digits of ``L`` (a power of
    two needs one squaring more)."""
    digits = list(powers)
    if not digits:   # L == 1
        return M
    if (1 << len(digits)) <= L:
        digits.append(digits[-1] @ digits[-1])
    out = None
    for j, P in enumerate(digits):
        if L >> j & 1:
            out = P if out is None else P @ out
    return out


def _same_pattern(fr, like) -> bool:
    """Whether the compiled loop ``like`` is of the same scenario and records as ``fr``
    (a :class:`~orchestrator.analysis.fast.FastResponse` being built) with blocks of the
    same non-zero patterns (so the same memory state)."""
    a, b = fr.lin, like.lin
    if (like.refs != fr.refs or a.n != b.n or list(a.order) != list(b.order)
            or a.blocks.keys() != b.blocks.keys()):
        return False
    for name, x in a.blocks.items():
        y = b.blocks[name]
        if x is y:
            continue
        if (x.kind, x.period, x.n) != (y.kind, y.period, y.n) or not np.array_equal(
                x.feedthrough, y.feedthrough):
            return False
        for u, v in ((x.A, y.A), (x.B, y.B), (x.C, y.C), (x.D, y.D)):
            if u.shape != v.shape or not np.array_equal(u != 0.0, v != 0.0):
                return False
    return True


def _tick_map(fr, k: int, cols=None):
    """``(M, N)`` of tick ``k`` of the loop ``fr``: ``X+ = M X + N w`` on the whole
    lifted state, ``M`` of the state columns ``cols`` only when given (the rows are
    independent combinations of the columns: the same numbers as those columns of the
    whole)."""
    lin, n, m = fr.lin, fr.lin.n, fr.m
    cols = np.arange(n) if cols is None else np.asarray(cols, int)
    c = cols.size
    X = np.zeros((n, c + m))
    X[cols, np.arange(c)] = 1.0

    def w_next(name):
        rows = np.zeros((len(lin.blocks[name].outputs), c + m))
        off = c + fr._in_off[name]
        rows[:, off:off + rows.shape[0]] = np.eye(rows.shape[0])
        return rows

    X = lin._tick(X, k, w_next)   # k < the super-period, a multiple of every period
    return X[:, :c], X[:, c:]


def _limit_bounds(fr, t, pos, X, Wus, actives) -> np.ndarray:
    """Upper bounds of ``|y|`` over the runs of one type ``t`` of the loop ``fr`` for
    the live rows ``pos``, per record, ``(E, len(pos))``: ``max_q |C_q M^q x_0| <=
    sum_j max_q |(C M^q)_ij| |x_0j|`` and ``|sum h_(q-l) w_l| <= sum_c (sum_p
    |h_p|_ic) max_l |w_lc|`` (Hoelder), summed per run and maximised over the runs;
    rigorous whatever the scales of the states.  ``X`` (E, n_u, s) the runs' start
    states, ``Wus`` each record's inputs of those runs (n_u, L, k), ``actives`` its
    channels.  The free parts of every record and run are one product."""
    def absmax():   # tick by tick: no temporary of the size of O (a 25 MB one stalls)
        O = t.O.reshape(t.L, t.live.size, -1)
        A = np.abs(O[0, pos])                                             # (p, s)
        buf = np.empty_like(A)
        for q in range(1, t.L):
            np.maximum(A, np.abs(np.take(O[q], pos, axis=0, out=buf), out=buf), out=A)
        return A

    A = fr._kept(("absmax", id(t), pos.tobytes()), absmax)
    E, n_u, s = X.shape
    b = (np.abs(X.reshape(E * n_u, s)) @ A.T).reshape(E, n_u, pos.size)
    for e, (Wu, active) in enumerate(zip(Wus, actives)):
        if active.size:
            h1 = fr._kept(("abssum", id(t), active.tobytes(), pos.tobytes()),   # (k, p)
                          lambda a=active: np.abs(fr._columns(t, a)[1][:, pos]).sum(axis=0).T)
            b[e] += np.abs(Wu).max(axis=1) @ h1                            # (n_u, p)
    return b.max(axis=1)


def _pair_power(a, L: int):
    """``a^L`` of a stack of 2x2 blocks ``a`` (n, 2, 2), by squaring."""
    out = np.broadcast_to(np.eye(2), a.shape).copy()
    sq = a
    while L:
        if L & 1:
            out = sq @ out
        L >>= 1
        if L:
            sq = sq @ sq
    return out


def _power_chain(L: int, square: float, product: float) -> tuple:
    """The cheapest ``(k, j, r)`` with ``L = k 2^j + r`` for ``M^L = M^r (M^k)^(2^j)``, and
    its flops: ``k - 1 + r`` structured products with ``M`` (``product`` flops each) and
    ``j`` dense squarings (``square`` each).  Where a product costs a fraction of a
    squaring (the coupling of a large model), a longer run of products before fewer
    squarings pays: at 500 modes, with isolation on, ``M^99`` as ``M^3 (M^12)^8`` costs
    4.8 squarings' flops against 6.4 by the binary digits of 99."""
    best = (None, _chain_flops(L, None, square, product))
    for j in range(L.bit_length()):
        k = L >> j
        chain = (k, j, L - (k << j))
        cost = _chain_flops(L, chain, square, product)
        if cost < best[1]:
            best = (chain, cost)
    return best


def _chain_flops(L: int, chain, square: float, product: float) -> float:
    """Flops of ``M^L`` by ``chain`` (:func:`_power_chain`), or by the binary digits of
    ``L``, left to right, for None (a factor ``M`` a structured product)."""
    if chain is None:
        return (L.bit_length() - 1) * square + (L.bit_count() - 1) * product
    k, j, r = chain
    return (k - 1 + r) * product + j * square


def _coupled_power(a, gamma, Zu, last) -> np.ndarray:
    """``M^L`` of ``M = blockdiag(a) + [gamma; 0] Lu + [0; I] MR`` (a structured tick map,
    :class:`~.structured._Form`) from its coupling's rows along the run: ``Zu[l] =
    Lu M^l`` (L, k, s) and ``last = MR M^(L-1)``.  Expanding ``M^L = Bd^L + sum_l
    Bd^(L-1-l) U W M^l``, the pair rows are ``a^L + sum_l a^(L-1-l) gamma Zu[l]`` (one
    product of ``(n_p, L k)`` by ``(L k, s)``) and the other rows ``last``.  At 500 modes
    with isolation on, 14.6 GFlop with the row Krylov products against 22.9 by squaring
    (261 against 388 ms on one core)."""
    L, k, s = Zu.shape
    n_p = 2 * a.shape[0]
    G = np.empty((n_p // 2, 2, L, k))   # G[:, :, l] = a^(L-1-l) gamma, pair by pair
    G[:, :, L - 1] = gamma.reshape(-1, 2, k)
    for j in range(L - 2, -1, -1):
        np.matmul(a, G[:, :, j + 1], out=G[:, :, j])
    ML = np.empty((s, s))
    np.matmul(G.reshape(n_p, L * k), Zu.reshape(L * k, s), out=ML[:n_p])
    ML[n_p:] = last
    _add_pairs(ML, _pair_power(a, L))
    return ML


def _add_pairs(M: np.ndarray, P: np.ndarray) -> None:
    """``M += blockdiag(P)`` on its first ``2 len(P)`` rows and columns (``P`` (n, 2, 2):
    the pairs' 2x2 blocks)."""
    i = np.arange(0, 2 * P.shape[0], 2)
    M[i, i] += P[:, 0, 0]
    M[i, i + 1] += P[:, 0, 1]
    M[i + 1, i] += P[:, 1, 0]
    M[i + 1, i + 1] += P[:, 1, 1]


class _BlockPower:
    """``M^L`` of a run whose coupling leaves pairs alone: their own 2x2 powers ``P``
    (at the pair states ``i``, ``i + 1`` for ``i`` in ``at``) plus the dense columns
    ``X`` of the others (``cols``).  Multiplies as the matrix (``@``); ``toarray()``,
    ``copy()`` and ``numpy.asarray`` give the matrix itself."""

    def __init__(self, s, at, P, cols, X):
        self.shape = (s, s)
        self.at, self.P, self.cols, self.X = at, P, cols, X
        # the pairs' rows, None when they are the leading states (multiplied in place)
        self._rows = (None if np.array_equal(at, 2 * np.arange(len(at)))
                      else (np.asarray(at)[:, None] + np.arange(2)).ravel())

    @property
    def nbytes(self) -> int:
        return self.P.nbytes + self.X.nbytes

    def __matmul__(self, Y):
        Y = np.asarray(Y)
        flat = Y.ndim == 1
        Y = Y.reshape(self.shape[0], -1)
        out = self.X @ Y[self.cols]
        if self._rows is None:
            pair_right(self.P, Y, out, add=True)
        else:   # the pairs' rows gathered, multiplied and put back
            part = out[self._rows]
            pair_right(self.P, Y[self._rows], part, add=True)
            out[self._rows] = part
        return out[:, 0] if flat else out

    def toarray(self) -> np.ndarray:
        """The matrix ``(s, s)``."""
        return self @ np.eye(self.shape[0])

    copy = toarray

    def __array__(self, dtype=None, copy=None):
        return self.toarray() if dtype is None else self.toarray().astype(dtype)
