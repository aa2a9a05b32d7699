"""The fast path: a linear scenario's whole record from its sources, by structure.

A :class:`~orchestrator.analysis.LinearScenario` steps the master's Gauss-Seidel ticks as
one linear map per tick.  Over a record of ``K`` ticks that is ``K`` dense products of
the whole lifted state: as slow as the co-simulation.  :class:`FastResponse` uses the
structure of the problem instead:

* **Memory state.**  Most of the lifted state (inputs set and outputs published at every
  tick) is overwritten before it is read; only the rows some tick reads carry memory
  (block states, outputs held between slower ticks), and of those only the ones a
  source reaches and a computed row sees (a loop at gain 0 drops out).  The maps act
  on those.
* **Runs.**  Within a hyperperiod, ticks with the same instances due have the same map
  ``x+ = M x + N w``, ``y = C x + D w``.  A *run* of ``L`` such ticks is one affine step
  ``x_end = M^L x_0 + sum_l M^(L-1-l) N w_l``, and its outputs are
  ``y_q = C M^q x_0 + sum_{l<=q} h_(q-l) w_l`` with the Markov parameters
  ``h_0 = D``, ``h_p = C M^(p-1) N``: a causal convolution, computed for every run at
  once by FFT.  The matrices of each run type are computed once per closed loop.
* **Only what drives.**  Source channels that are zero over the record drop out; the
  input side of a run type (its column Krylov products) is built per channel, on first
  use, so a loop driven by one source pays for that source alone.
* **Records together.**  The events of one configuration share its loop:
  :meth:`FastResponse.run_many` runs their state recursions as one product per run and
  their free responses as one product per run type (every record in it).

The result equals :meth:`LinearScenario.simulate` to round-off (tested), which equals
the co-simulation of a linear scenario to round-off.  Where the FMUs would leave the
linear model (a rail, a slew or torque limit reached), :meth:`FastResponse.run` names
the instance and the first time, in one sentence (:class:`NonlinearError`).
"""

from __future__ import annotations

import math
import threading

import numpy as np
import scipy.fft as sfft

from .blocks import AnalysisError
from .fastparts import (NonlinearError, Record, _add_forced, _causal_conv, _doubling,
                        _fft_length, _inner_basis, _inner_bound, _inner_checks, _limit_bounds,
                        _power, _powers, _relevant, _run_views, _RunType, _same_pattern,
                        _tick_map)
from .steady import SteadyState

__all__ = ["FastResponse", "NonlinearError", "Record"]

# ticks a super-period covers at least: short hyperperiods (a single-rate loop has one
# tick) are repeated so that runs are long and few
_MIN_TICKS = 64
# runs up to this long convolve with their block-Toeplitz matrix, longer ones by FFT
# (measured crossover at one BLAS thread: a 99-tick run of 6 channels and 48 rows takes
# 10.7 ms by its kept Toeplitz product, 5.1 ms by FFT, and the Toeplitz matrix 15 ms to
# build; at 16 ticks the product wins, 1.5 against 2.1 ms)
_TOEPLITZ_TICKS = 24
# tick times, (start, base, n_ticks, every) -> times: they depend on the grid's start and
# base step alone, so every loop on that grid (a Monte Carlo's samples) shares them
_TIMES: dict = {}


class FastResponse(SteadyState):
    """A linear scenario compiled for whole records.

    Parameters
    ----------
    lin : LinearScenario
        The closed loop (:func:`~orchestrator.analysis.linearize`).
    refs : sequence of str
        Published outputs ``instance.variable`` to record.  The outputs the blocks
        declare as limited (piezo voltage and current, ACS torques) are computed too and
        checked on every record.
    strict : bool
        Refuse an instance holding something the linear model leaves out (default);
        False compiles its linear part (what a transfer needs).
    like : FastResponse, optional
        A compiled loop of the same scenario whose blocks have the same non-zero
        patterns (a Monte Carlo sample's loop and its nominal one): its memory state is
        taken rather than found again, and the tick maps are built on those columns
        only.  A block whose pattern differs (a loop at gain 0 switched on) makes this
        loop find its own.

    Raises
    ------
    AnalysisError
        When an instance holds something the linear model leaves out (one sentence per
        instance; unless ``strict`` is False), or a reference is not an output of the
        scenario.
    """

    def __init__(self, lin, refs, strict: bool = True, like=None):
        self.lin = lin
        self.refs = tuple(refs)
        reasons = [u for b in lin.blocks.values() for u in b.unmodelled
                   if not u.startswith("output ")]
        for ref in self.refs:
            b = lin.blocks.get(ref.partition(".")[0])
            if b is not None:
                reasons += [u for u in b.unmodelled if u.startswith(f"output {ref} ")]
        if reasons and strict:
            raise AnalysisError("the linear engine cannot represent " + "; ".join(reasons)
                                + ": run these cases with the co-simulation (--engine cosim)")
        self._checks = [(f"{n}.{o}", lo, hi, what) for n, b in lin.blocks.items()
                        for o, lo, hi, what in b.limits]
        # a limit flag is zero wherever the limits are kept, which run() checks
        self._zero = [j for j, r in enumerate(self.refs) if self._is_flag(r)]
        computed = [r for r in self.refs if not self._is_flag(r)]
        self._computed = [j for j, r in enumerate(self.refs) if not self._is_flag(r)]
        # a checked output that is also recorded is computed once
        extra = [c[0] for c in self._checks if c[0] not in computed]
        self._check_col = [computed.index(c[0]) if c[0] in computed
                           else len(computed) + extra.index(c[0]) for c in self._checks]
        # limits inside a step: values at every sub-step, from the rows of the block's
        # state (the previous tick's: its step's start) and the inputs held that they
        # read (computed too)
        r0 = len(computed) + len(extra)
        basis, self._inner = _inner_basis(lin, r0)
        self._inner_cols = np.arange(r0, r0 + len(basis))
        rows = [lin.index(r) for r in computed] + [lin.index(r) for r in extra] + basis
        self._r = len(rows)
        # exogenous inputs: every source output, in block order
        self.inputs = [(n, j) for n in lin.sources for j in range(len(lin.blocks[n].outputs))]
        self._in_off = {}
        off = 0
        for n in lin.sources:
            self._in_off[n] = off
            off += len(lin.blocks[n].outputs)
        self.m = off
        periods = [lin.hyper] + [lin.blocks[n].period for n in lin.sources]
        P = int(np.lcm.reduce(periods))
        self.P = P * max(1, math.ceil(_MIN_TICKS / P))   # the super-period
        sigs = [self._signature(k) for k in range(self.P)]
        first = {}
        for k, sig in enumerate(sigs):
            first.setdefault(sig, k)
        if like is not None and _same_pattern(self, like):
            S = like._S   # the tick maps on the memory state's columns alone
            maps = {sig: _tick_map(self, k, S) for sig, k in first.items()}
        else:
            maps = {sig: _tick_map(self, k) for sig, k in first.items()}  # a kind of tick each
            read = np.zeros(lin.n, bool)
            for M, _ in maps.values():
                read |= np.any(M != 0.0, axis=0)
            S = np.flatnonzero(read & _relevant(maps, rows))
            maps = {sig: (M[:, S], N) for sig, (M, N) in maps.items()}
        self._S = S
        self.n_memory = S.size
        self._maps = {sig: (M[S], N[S], M[rows], N[rows]) for sig, (M, N) in maps.items()}
        # the super-period as runs of one signature
        self._runs = []
        k = 0
        while k < self.P:
            j = k
            while j + 1 < self.P and sigs[j + 1] == sigs[k]:
                j += 1
            self._runs.append((sigs[k], j - k + 1))
            k = j + 1
        self._types = {}
        self._schur = None
        self._kernels = {}

    # ------------------------------------------------------------------ compile
    def _is_flag(self, ref: str) -> bool:
        inst, _, var = ref.partition(".")
        b = self.lin.blocks.get(inst)
        return b is not None and var in b.flags

    def _signature(self, k: int) -> tuple:
        return tuple(k % b.period == 0 for b in self.lin.blocks.values())

    def _type(self, sig, L: int) -> _RunType:
        key = (sig, L)
        t = self._types.get(key)
        if t is not None:
            return t
        M, N, C, D = self._maps[sig]
        s = M.shape[0]
        # a row is zero by structure when its C and D rows are: C M^q and C M^(p-1) N
        live = np.flatnonzero(np.any(C != 0, axis=1) | np.any(D != 0, axis=1))
        powers = _powers(M, L)
        # row Krylov C M^q, q = 0 .. L-1, of the live rows, by doubling: the rows
        # q in [2^j, 2^(j+1)) are those of [0, 2^j) times M^(2^j), one product each
        O = np.empty((L, live.size, s))
        O[0] = C[live]
        for P, (lo, hi) in zip(powers, _doubling(L)):
            O[lo:hi] = (O[:hi - lo].reshape(-1, s) @ P).reshape(hi - lo, live.size, s)
        t = _RunType(L, _power(M, L, powers), O.reshape(L * live.size, s), live, M, N,
                     np.ascontiguousarray(D[live]), {}, powers)
        self._types[key] = t
        return t

    def _columns(self, t: _RunType, active) -> tuple:
        """``(G, h)`` of a run type for the source channels ``active``: ``G`` (s, L, k)
        ``M^(L-1-l) N``, ``h`` (L, r_live, k) the Markov parameters ``h_0 = D``,
        ``h_p = C M^(p-1) N`` (column Krylov of the channels not built before)."""
        def make():   # built once when a campaign's cases ask from several threads
            with self._building():
                miss = [int(c) for c in active if int(c) not in t.cols]
                if miss:
                    self._store_columns(t, miss, self._column_krylov(t, miss))
                return tuple(np.stack([t.cols[int(c)][i] for c in active], axis=-1)
                             for i in (0, 1))
        # kept: every record asks
        return self._kept(("cols", id(t), np.asarray(active, int).tobytes()), make)

    def _building(self):
        """The lock under which run types and input sides are built (records of one
        loop asked from several threads build each once)."""
        return self.__dict__.setdefault("_build_lock", threading.RLock())

    def _store_columns(self, t: _RunType, miss, K) -> None:
        """Keep ``M^(L-1-l) N`` and the Markov parameters ``C (M^(p-1) N)`` (one product,
        no pass over every row ``C M^q``) of the channels ``miss`` of a run type from
        their column Krylov products ``K`` (s, L, c)."""
        L, s, r = t.L, t.N.shape[0], t.live.size
        h = np.empty((L, r, len(miss)))
        h[0] = t.D[:, miss]
        if L > 1:
            h[1:] = np.moveaxis((t.O[:r] @ K[:, :L - 1].reshape(s, -1)).reshape(r, L - 1, -1), 0, 1)
        for j, ch in enumerate(miss):
            t.cols[ch] = (np.ascontiguousarray(K[:, ::-1, j]), h[:, :, j].copy())

    def _column_krylov(self, t: _RunType, miss) -> np.ndarray:
        """``M^q N`` of the channels ``miss``, ``(s, L, c)``, by doubling (as the rows)."""
        L, s, c = t.L, t.N.shape[0], len(miss)
        K = np.empty((s, L, c))
        K[:, 0] = t.N[:, miss]
        for P, (lo, hi) in zip(t.powers, _doubling(L)):
            K[:, lo:hi] = (P @ K[:, :hi - lo].reshape(s, -1)).reshape(s, hi - lo, c)
        return K

    def prepare(self, channels=None) -> "FastResponse":
        """Build every run type and its input side for ``channels`` (default every
        source channel) now, rather than on a record's first use.

        Parameters
        ----------
        channels : sequence of int, optional
            Source channels whose input side to build (default all; empty: the run
            types alone, each channel's side built when a record first drives it).

        Returns
        -------
        FastResponse
            This loop.
        """
        cols = np.arange(self.m) if channels is None else np.asarray(channels, int)
        for sig, L in self._runs:
            t = self._type(sig, L)
            if cols.size:
                self._columns(t, cols)
        return self

    def _forced(self, t: _RunType, active, Wu, sel=None) -> np.ndarray:
        """The Markov convolution ``sum_(l<=q) h_(q-l) w_l`` of every run, ``(n_u, L
        r_sel)``, of the live rows ``sel`` (default all): one product with the
        block-Toeplitz matrix of ``h`` (kept per run type, channels and rows) for runs of
        up to ``_TOEPLITZ_TICKS`` ticks, by FFT beyond."""
        L, k = t.L, active.size
        sel = np.arange(t.live.size) if sel is None else sel
        r = sel.size

        def make():
            h = self._columns(t, active)[1][:, sel]                     # (L, r, k)
            if L > _TOEPLITZ_TICKS:
                return ("fft", sfft.rfft(h, _fft_length(L), axis=0))    # (f, r, k)
            # Tt[l, c, q, j] = h[q - l, j, c] for q >= l, from a sliding view
            hp = np.concatenate([np.zeros((L - 1, k, r)), h.transpose(0, 2, 1)])
            win = np.lib.stride_tricks.sliding_window_view(hp, L, axis=0)  # (L, k, r, L)
            return ("toeplitz", np.ascontiguousarray(
                win[::-1].transpose(0, 1, 3, 2)).reshape(L * k, L * r))
        T = self._kept(("forced", id(t), active.tobytes(), sel.tobytes()), make)
        if T[0] == "fft":
            return _causal_conv(T[1], Wu).reshape(Wu.shape[0], L * r)
        return Wu.reshape(Wu.shape[0], L * k) @ T[1]

    def _kept(self, key, make):
        """A derived matrix of this loop, ``make()`` on first use and kept (bounded; keys
        name a run type by ``id``)."""
        got = self._kernels.get(key)
        if got is None:
            if len(self._kernels) > 256:
                self._kernels.clear()
            got = self._kernels[key] = make()
        return got

    def _rows(self, t: _RunType, sel) -> np.ndarray:
        """``C M^q`` of the live rows ``sel`` of a run type, ``(L r_sel, s)`` (kept)."""
        if sel.size == t.live.size:
            return t.O
        # take: 30 times a fancy index's speed here
        return self._kept(("rows", id(t), sel.tobytes()), lambda: np.take(
            t.O.reshape(t.L, t.live.size, -1), sel, axis=1).reshape(t.L * sel.size, -1))

    # ------------------------------------------------------------------ running
    def times(self, n_ticks: int, every: int = 1) -> np.ndarray:
        """Exact times (s) of the ticks ``0, every, 2 every, ...`` up to ``n_ticks``.

        Parameters
        ----------
        n_ticks : int
            Last tick.
        every : int
            Tick stride (a source's period, the output interval).

        Returns
        -------
        ndarray, shape (n_ticks // every + 1,)
            Read-only, cached.
        """
        tb = self.lin.plan.timebase
        key = (tb.start, tb.base, n_ticks, every)
        t = _TIMES.get(key)
        if t is None:
            t = np.array(tb.times(range(0, n_ticks + 1, every)))
            t.flags.writeable = False
            if len(_TIMES) > 32:
                _TIMES.clear()
            _TIMES[key] = t
        return t

    def input_matrix(self, series: dict, n_ticks: int) -> np.ndarray:
        """Source values ``W`` (n_ticks + 1, m) from each source's values.

        Parameters
        ----------
        series : dict of str to ndarray, shape (n_due, n_out)
            Per source, its outputs at its due ticks ``0, p, 2p, ...`` up to
            ``n_ticks``; a source left out publishes zeros.
        n_ticks : int
            Last tick of the record.

        Returns
        -------
        ndarray, shape (n_ticks + 1, m)
        """
        W = np.zeros((n_ticks + 1, self.m))
        for name, vals in series.items():
            if name not in self._in_off:
                raise AnalysisError(f"{name!r} is not a source of the scenario; sources: "
                                    f"{', '.join(self.lin.sources)}")
            p = self.lin.blocks[name].period
            off = self._in_off[name]
            vals = np.asarray(vals, float)
            W[::p, off:off + vals.shape[1]] = vals
        return W

    def source_series(self, n_ticks: int, only=None) -> dict:
        """Each source's outputs at its due ticks, from its own ``series``.

        Parameters
        ----------
        n_ticks : int
            Last tick of the record.
        only : sequence of str, optional
            Sources to evaluate (default all).

        Raises
        ------
        AnalysisError
            For a source whose outputs are not a function of time alone (an input-driven
            wheel, or a source taken out of the loop).
        """
        out = {}
        for name in (self.lin.sources if only is None else only):
            b = self.lin.blocks[name]
            if b.series is None:
                raise AnalysisError(f"source {name!r} has no open-loop series (an input-"
                                    "driven wheel, or an instance taken out of the loop); "
                                    "the linear engine cannot drive it")
            out[name] = b.series(self.times(n_ticks, b.period))
        return out

    def run(self, W: np.ndarray, check: bool = True) -> Record:
        """The record driven by ``W`` (n_ticks + 1, m), from rest.

        Parameters
        ----------
        W : ndarray, shape (n_ticks + 1, m)
            Source values at every tick (:meth:`input_matrix`).
        check : bool
            Raise :class:`NonlinearError` when a limited output leaves its range.

        Returns
        -------
        Record
        """
        return self.run_many([W], check)[0]

    def run_many(self, Ws, check: bool = True, bound_limits: bool = False,
                 scales=None, actives=None, start: int = 0) -> list:
        """The records driven by each ``W`` of ``Ws``, from rest, computed together.

        The events of one configuration share its loop: their state recursions are one
        product per run for all of them, and their free responses one product per run
        type.  The result equals :meth:`run` of each.

        Parameters
        ----------
        Ws : sequence of ndarray, each of shape (n_ticks + 1, m)
            Source values at every tick (:meth:`input_matrix`), the same ``n_ticks``.
        check : bool
            Raise :class:`NonlinearError` when a limited output of a record leaves its
            range (the first such record); else each record's ``limits`` say how much
            of each range it used (above 1: reached).
        bound_limits : bool
            Checked outputs that are not recorded are computed only where a rigorous
            bound (:func:`.fastparts._limit_bounds`) does not keep them inside their range; where
            it does, ``limits`` holds that bound (an upper bound of the fraction used).
            ``reached`` is exact either way.  What Monte Carlo uses: its records need
            their references and the knowledge that no rail is reached.
        scales : sequence of ndarray, shape (m,), optional
            Per record, a factor on each source channel: the record of ``W * scale``
            without that copy of ``W`` (a Monte Carlo sample's amplitudes).
        actives : sequence of (ndarray of int or None), optional
            Per record, the source channels its ``W`` drives (None, or no sequence: the
            columns of ``W`` that are not all zero; a channel listed but zero costs only
            time).
        start : int
            The first tick whose recorded references are needed: a run that ends before
            it computes only the checked outputs a bound does not clear, and its
            references are NaN (what a campaign's ``skip`` discards).

        Returns
        -------
        list of Record
        """
        Ws = [np.asarray(W, float) for W in Ws]
        if not Ws:
            return []
        K = Ws[0].shape[0]
        if any(W.shape != (K, self.m) for W in Ws):
            raise AnalysisError(f"every input matrix of a batch must have shape ({K}, "
                                f"{self.m}); got {', '.join(str(W.shape) for W in Ws)}")
        E, s = len(Ws), self.n_memory
        actives = [np.flatnonzero(np.any(W != 0.0, axis=0)) if a is None else
                   np.asarray(a, int) for W, a in zip(Ws, actives or [None] * E)]
        r = self._r
        # the runs of the record, in order: (type key, start)
        units = []
        k = 0
        while k < K:
            for sig, L in self._runs:
                if k >= K:
                    break
                units.append(((sig, min(L, K - k)), k))
                k += L
        by_type = {}
        for i, (key, _) in enumerate(units):
            by_type.setdefault(key, []).append(i)
        with self._building():   # a record's last, shorter run: a type built once
            types = {key: self._type(*key) for key in by_type}
        windows = {key: np.array([units[i][1] for i in idx])[:, None] + np.arange(types[key].L)
                   for key, idx in by_type.items()}
        # input contribution to each run's end state, per run type and record
        if scales is None:
            Was = [W[:, active] for W, active in zip(Ws, actives)]
        else:
            if len(scales) != E:
                raise AnalysisError(f"{len(scales)} channel scales for {E} input matrices")
            Was = [W[:, active] * np.asarray(sc, float)[active]
                   for W, active, sc in zip(Ws, actives, scales)]
        union = np.unique(np.concatenate(actives))
        if union.size:   # the column Krylov of every channel a record drives, at once
            for t in types.values():
                self._columns(t, union)
        g = np.zeros((len(units), s, E))
        for e, (Wa, active) in enumerate(zip(Was, actives)):
            if active.size == 0:
                continue
            for key, idx in by_type.items():
                G, _ = self._columns(types[key], active)
                Wu = Wa[windows[key]]                                  # (n_u, L, k)
                g[idx, :, e] = Wu.reshape(len(idx), -1) @ G.reshape(s, -1).T
        # the state recursion, one product per run for every record
        X0 = np.empty((E, len(units), s))
        x = np.zeros((s, E))
        for i, (key, _) in enumerate(units):
            X0[:, i] = x.T
            x = types[key].ML @ x + g[i]
        # checked outputs that are not recorded, bounded instead of computed where the
        # bound keeps them inside their range
        n_ref = len(self._computed)
        bounds, skip = np.zeros((E, r)), np.zeros(r, bool)
        if bound_limits and r > n_ref:
            for key, idx in by_type.items():
                t = types[key]
                pos = np.flatnonzero(t.live >= n_ref)
                b = _limit_bounds(self, t, pos, X0[:, idx],
                                   [Wa[windows[key]] for Wa in Was], actives)
                bounds[:, t.live[pos]] = np.maximum(bounds[:, t.live[pos]], b)
            room = np.full(r, -np.inf)
            for j, (_, lo, hi, _) in enumerate(self._checks):
                c = self._check_col[j]
                if c >= n_ref and hi > 0 and lo < 0:
                    room[c] = min(hi, -lo)
            # a margin far above the round-off of the bound itself
            skip = np.all(bounds * (1.0 + 1e-6) < room, axis=0)
            skip[self._inner_cols] = True   # a block's sub-steps: all its limits cleared
            for _, G, lo, hi, _, cols, _, _ in self._inner:
                skip[cols] &= hi > 0 and lo < 0 and bool(np.all(   # every record at once
                    _inner_bound(G, bounds[:, cols].T) * (1.0 + 1e-6) < min(hi, -lo)))
        # outputs: C M^q x_0 + (h * w), per run type
        # Y holds the computed rows alone (a bounded row is not), in row order
        need = np.flatnonzero(~skip)
        at = np.cumsum(~skip) - 1           # the column of each computed row
        Y = np.zeros((E, K, need.size))
        checked = np.zeros(r, bool)
        checked[self._check_col] = checked[self._inner_cols] = True
        if start > 0:   # a reference no limit checks is not needed before start
            Y[:, :start, at[np.flatnonzero(~checked[:n_ref])]] = np.nan
        for key, idx in by_type.items():
            t = types[key]
            early = windows[key][:, -1] < start
            for part, refs_too in ((~early, True), (early, False)):
                sel = np.flatnonzero(~skip[t.live] & (refs_too | checked[t.live]))
                if not part.any() or not sel.size:
                    continue
                pidx, win = np.asarray(idx)[part], windows[key][part]
                n_u = len(pidx)
                views = _run_views(Y, win, sel.size == need.size)   # in place: no copy
                # the free parts, every record in one product (17 against 20 ms apart)
                out = (X0[:, pidx].reshape(E * n_u, s) @ self._rows(t, sel).T).reshape(
                    E, n_u, t.L * sel.size)
                if views is not None:
                    views[...], out = out, views
                for e, (Wa, active) in enumerate(zip(Was, actives)):
                    if active.size:
                        _add_forced(out[e], Wa[win], self._forced, t, active, sel)
                if views is not None:
                    continue
                out = out.reshape(E, n_u * t.L, sel.size)
                Y[:, win.ravel()[:, None], at[t.live[sel]]] = out
        return [self._record(y, check, np.where(skip, b, np.nan), bound_inner=bound_limits)
                for y, b in zip(Y, bounds)]

    def _record(self, Y: np.ndarray, check: bool, bounds=None, bound_inner: bool = False) -> Record:
        """A record from the computed rows ``Y`` (n_ticks + 1, computed rows): limits
        checked.  ``bounds`` (r,): where not NaN, the row was not computed (``Y`` leaves
        it out) and this bounds it.  ``bound_inner``: a limit inside a step is bounded
        from its rows' largest values where that clears it (``reached`` stays exact)."""
        K = Y.shape[0]
        times = self.times(K - 1)
        n_ref = len(self._computed)
        limits, reached, bounded = {}, [], []
        cols = np.asarray(self._check_col, int)
        at = None   # the column of Y holding each computed row
        if bounds is not None:   # the rows a bound stands for were not computed
            computed = np.isnan(bounds)
            at = np.cumsum(computed) - 1
            cols = cols[computed[cols]]
        cols = np.unique(cols)
        ycols = cols if at is None else at[cols]
        top = dict(zip(cols.tolist(), Y[:, ycols].max(axis=0).tolist()))
        bottom = dict(zip(cols.tolist(), Y[:, ycols].min(axis=0).tolist()))
        for j, (ref, lo, hi, what) in enumerate(self._checks):
            c = self._check_col[j]
            if bounds is not None and not np.isnan(bounds[c]):
                limits[ref] = float(bounds[c] / min(hi, -lo))
                bounded.append(ref)
                continue
            used = max(top[c] / hi if hi > 0 else 0.0, bottom[c] / lo if lo < 0 else 0.0)
            limits[ref] = float(used)
            if not (top[c] > hi or bottom[c] < lo):
                continue
            reached.append(ref)
            if check:
                y = Y[:, c if at is None else at[c]]
                bad = np.flatnonzero((y > hi) | (y < lo))[0]
                raise NonlinearError(
                    f"{ref} reaches its {what} ({y[bad]:.4g} outside [{lo:.4g}, {hi:.4g}]) "
                    f"at t = {times[bad]:.6g} s, where the FMU leaves the linear model: "
                    "run this case with the co-simulation (--engine cosim)")
        _inner_checks(self._inner, Y, at, bounds, limits, reached, times, check, bound_inner,
                      bounded)
        if self._zero:
            values = np.zeros((K, len(self.refs)))
            values[:, self._computed] = Y[:, :n_ref]
        else:
            values = np.ascontiguousarray(Y[:, :n_ref])
        return Record(values, times, self.refs, limits, tuple(reached),
                      tuple(dict.fromkeys(bounded)))

    def ref_rows(self, refs) -> np.ndarray:
        """Rows of the computed outputs (``Y`` columns) holding ``refs``."""
        computed = [self.refs[j] for j in self._computed]
        missing = [r for r in refs if r not in computed]
        if missing:
            raise AnalysisError(f"{missing[0]!r} is not among the recorded outputs of the "
                                f"compiled scenario ({', '.join(computed[:8])} ...)")
        return np.array([computed.index(r) for r in refs], int)
