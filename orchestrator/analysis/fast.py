"""The fast path: a linear scenario's whole record from its sources, by structure.

A :class:`~orchestrator.analysis.LinearScenario` steps the master's Gauss-Seidel ticks as
one linear map per tick.  Over a record of ``K`` ticks that is ``K`` dense products of
the whole lifted state: as slow as the co-simulation.  :class:`FastResponse` uses the
structure of the problem instead:

* **Memory state.**  Most of the lifted state (inputs set and outputs published at every
  tick) is overwritten before it is read; only the rows some tick reads carry memory
  (block states, outputs held between slower ticks).  The maps act on those.
* **Runs.**  Within a hyperperiod, ticks with the same instances due have the same map
  ``x+ = M x + N w``, ``y = C x + D w``.  A *run* of ``L`` such ticks is one affine step
  ``x_end = M^L x_0 + sum_l M^(L-1-l) N w_l``, and its outputs are
  ``y_q = C M^q x_0 + sum_{l<=q} h_(q-l) w_l`` with the Markov parameters
  ``h_0 = D``, ``h_p = C M^(p-1) N``: a causal convolution, computed for every run at
  once by FFT.  The matrices of each run type are computed once per closed loop.
* **Only what drives.**  Source channels that are zero over the record drop out.

The state recursion is then one small product per run (80 for an 8 s record at a 0.1 s
hyperperiod) and everything else is a few large matrix products: the cost of a record
is about that of its outputs, ``n_outputs x n_memory x n_ticks``.

The result equals :meth:`LinearScenario.simulate` to round-off (tested), which equals
the co-simulation of a linear scenario to round-off.  Where the FMUs would leave the
linear model (a rail, a slew or torque limit reached), :meth:`FastResponse.run` names
the instance and the first time, in one sentence (:class:`NonlinearError`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft

from .blocks import AnalysisError

__all__ = ["FastResponse", "NonlinearError", "Record"]

# ticks a super-period covers at least: short hyperperiods (a single-rate loop has one
# tick) are repeated so that runs are long and few
_MIN_TICKS = 64


class NonlinearError(AnalysisError):
    """A record leaves the linear model: a rail or limit of an FMU is reached."""


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
    """

    values: np.ndarray
    times: np.ndarray
    refs: tuple
    limits: dict

    def __iter__(self):
        return iter((self.values, self.times))

    def column(self, ref: str) -> np.ndarray:
        """The record of ``ref``."""
        return self.values[:, self.refs.index(ref)]


@dataclass(frozen=True)
class _RunType:
    """Matrices of a run of ``L`` ticks with one map (memory state ``s``, ``r`` rows)."""

    L: int
    ML: np.ndarray      # (s, s)       M^L
    G: np.ndarray       # (s, L, m)    M^(L-1-l) N
    O: np.ndarray       # (L * r_live, s)  C M^q, the rows that are not zero by structure
    h: np.ndarray       # (L, r_live, m)   Markov parameters, h_0 = D
    live: np.ndarray    # (r_live,)    those rows (e.g. a loop at gain 0 leaves its own out)


class FastResponse:
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

    Raises
    ------
    AnalysisError
        When an instance holds something the linear model leaves out (one sentence per
        instance; unless ``strict`` is False), or a reference is not an output of the
        scenario.
    """

    def __init__(self, lin, refs, strict: bool = True):
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
        rows = [lin.index(r) for r in computed] + [lin.index(r) for r in extra]
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
        maps = {sig: self._tick_map(k) for sig, k in first.items()}   # one per kind of tick
        n = lin.n
        read = np.zeros(n, bool)
        for M, _ in maps.values():
            read |= np.any(M != 0.0, axis=0)
        S = np.flatnonzero(read)
        self.n_memory = S.size
        self._maps = {sig: (M[np.ix_(S, S)], N[S], M[np.ix_(rows, S)], N[rows])
                      for sig, (M, N) in maps.items()}
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
        self._times = {}
        self._kernels = {}

    # ------------------------------------------------------------------ compile
    def _is_flag(self, ref: str) -> bool:
        inst, _, var = ref.partition(".")
        b = self.lin.blocks.get(inst)
        return b is not None and var in b.flags

    def _signature(self, k: int) -> tuple:
        return tuple(k % b.period == 0 for b in self.lin.blocks.values())

    def _tick_map(self, k: int):
        """``(M, N)`` of tick ``k``: ``X+ = M X + N w`` on the whole lifted state."""
        lin, n, m = self.lin, self.lin.n, self.m
        X = np.zeros((n, n + m))
        X[:, :n] = np.eye(n)

        def w_next(name):
            rows = np.zeros((len(lin.blocks[name].outputs), n + m))
            off = n + self._in_off[name]
            rows[:, off:off + rows.shape[0]] = np.eye(rows.shape[0])
            return rows

        X = lin._tick(X, k, w_next)   # k < the super-period, a multiple of every period
        return X[:, :n], X[:, n:]

    def _conv(self, key, t: _RunType, active, Wu):
        """The Markov convolution of a run type with the active inputs (kernel cached)."""
        if t.L <= 8:
            return _causal_conv(t.h[:, :, active], Wu)
        ck = (key, active.tobytes())
        Hf = self._kernels.get(ck)
        if Hf is None:
            Hf = sfft.rfft(t.h[:, :, active], _fft_length(t.L), axis=0)
            if len(self._kernels) > 64:
                self._kernels.clear()
            self._kernels[ck] = Hf
        return _causal_conv(t.h[:, :, active], Wu, Hf)

    def _type(self, sig, L: int) -> _RunType:
        key = (sig, L)
        t = self._types.get(key)
        if t is not None:
            return t
        M, N, C, D = self._maps[sig]
        s, m, r = M.shape[0], N.shape[1], C.shape[0]
        # column Krylov K_q = M^q N and row Krylov C M^q, q = 0 .. L-1
        K = np.empty((L, s, m))
        O = np.empty((L, r, s))
        K[0], O[0] = N, C
        for q in range(1, L):
            K[q] = M @ K[q - 1]
            O[q] = O[q - 1] @ M
        ML = np.linalg.matrix_power(M, L)
        G = K[::-1].transpose(1, 0, 2)                       # (s, L, m): M^(L-1-l) N
        h = np.empty((L, r, m))
        h[0] = D
        if L > 1:
            h[1:] = np.einsum("qrs,sm->qrm", O[:L - 1], N)   # C M^(p-1) N
        live = np.flatnonzero(np.any(O != 0, axis=(0, 2)) | np.any(h != 0, axis=(0, 2)))
        t = _RunType(L, ML, np.ascontiguousarray(G),
                     np.ascontiguousarray(O[:, live]).reshape(L * live.size, s),
                     np.ascontiguousarray(h[:, live]), live)
        self._types[key] = t
        return t

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
        key = (n_ticks, every)
        t = self._times.get(key)
        if t is None:
            t = np.array(self.lin.plan.timebase.times(range(0, n_ticks + 1, every)))
            t.flags.writeable = False
            self._times[key] = t
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
        W = np.asarray(W, float)
        K = W.shape[0]
        active = np.flatnonzero(np.any(W != 0.0, axis=0))
        Wa = W[:, active]
        r = len(self._computed) + len(set(self._check_col) - set(range(len(self._computed))))
        Y = np.zeros((K, r))
        s = self.n_memory
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
        for i, (key, start) in enumerate(units):
            by_type.setdefault(key, []).append(i)
        # input contribution to each run's end state, per run type
        g = np.zeros((len(units), s))
        for key, idx in by_type.items():
            t = self._type(*key)
            if active.size == 0:
                continue
            starts = np.array([units[i][1] for i in idx])
            Wu = Wa[starts[:, None] + np.arange(t.L)]            # (n_u, L, m_a)
            Ga = t.G[:, :, active].reshape(s, -1)
            g[idx] = Wu.reshape(len(idx), -1) @ Ga.T
        # the state recursion, one product per run
        X0 = np.empty((len(units), s))
        x = np.zeros(s)
        for i, (key, _) in enumerate(units):
            X0[i] = x
            x = self._types[key].ML @ x + g[i]
        # outputs: C M^q x_0 + (h * w), per run type
        for key, idx in by_type.items():
            t = self._type(*key)
            starts = np.array([units[i][1] for i in idx])
            free = (t.O @ X0[idx].T).T.reshape(len(idx), t.L, t.live.size)
            if active.size:
                Wu = Wa[starts[:, None] + np.arange(t.L)]
                free += self._conv(key, t, active, Wu)
            rows = (starts[:, None] + np.arange(t.L)).ravel()
            if t.live.size == r:
                Y[rows] = free.reshape(-1, r)
            else:
                Y[rows[:, None], t.live] = free.reshape(-1, t.live.size)
        times = self.times(K - 1)
        n_ref = len(self._computed)
        limits = {}
        top, bottom = Y.max(axis=0)[self._check_col], Y.min(axis=0)[self._check_col]
        for j, (ref, lo, hi, what) in enumerate(self._checks):
            used = max(top[j] / hi if hi > 0 else 0.0, bottom[j] / lo if lo < 0 else 0.0)
            limits[ref] = float(used)
            if check and (top[j] > hi or bottom[j] < lo):
                y = Y[:, self._check_col[j]]
                bad = np.flatnonzero((y > hi) | (y < lo))[0]
                raise NonlinearError(
                    f"{ref} reaches its {what} ({y[bad]:.4g} outside [{lo:.4g}, {hi:.4g}]) "
                    f"at t = {times[bad]:.6g} s, where the FMU leaves the linear model: "
                    "run this case with the co-simulation (--engine cosim)")
        if self._zero:
            values = np.zeros((K, len(self.refs)))
            values[:, self._computed] = Y[:, :n_ref]
        else:
            values = Y[:, :n_ref]
        return Record(values, times, self.refs, limits)

    # ------------------------------------------------------------------ steady state
    def period_map(self) -> np.ndarray:
        """The memory state's map over one super-period, ``(n_memory, n_memory)``."""
        Phi = np.eye(self.n_memory)
        for sig, L in self._runs:
            Phi = self._type(sig, L).ML @ Phi
        return Phi

    def period_schur(self) -> tuple:
        """Sorted complex Schur form of the balanced super-period map, kept once computed
        (a second sweep or steady state on this loop reuses it).

        Exact power-of-two balancing first (the memory state mixes metres, volts and
        strains).  Eigenvalues at 1 (rigid-body modes of an open attitude loop,
        integrators) come last: a line whose ``z = exp(j 2 pi f P base)`` is 1 makes
        ``z I - T`` singular there, and :meth:`steady_state` solves that block by least
        squares (the steady state exists; only a constant along the null direction is
        free).

        Returns
        -------
        (T, Q, n_top, scale)
            ``D^-1 Phi D = Q T Q^H`` with ``D = diag(scale)``; ``T[:n_top, :n_top]``
            holds the eigenvalues away from 1.
        """
        if self._schur is None:
            import scipy.linalg as la

            Phi_b, scale = balance(self.period_map())
            T, Q, k_top = la.schur(Phi_b, output="complex",
                                   sort=lambda v: abs(v - 1.0) > _UNIT_EIG_TOL)
            self._schur = (T, Q, int(k_top), scale)
        return self._schur

    def ref_rows(self, refs) -> np.ndarray:
        """Rows of the computed outputs (``Y`` columns) holding ``refs``."""
        computed = [self.refs[j] for j in self._computed]
        missing = [r for r in refs if r not in computed]
        if missing:
            raise AnalysisError(f"{missing[0]!r} is not among the recorded outputs of the "
                                f"compiled scenario ({', '.join(computed[:8])} ...)")
        return np.array([computed.index(r) for r in refs], int)

    def steady_state(self, freqs_hz, phasors, refs, chunk: int = 256) -> np.ndarray:
        """Periodic steady state of ``refs`` under harmonic sources, one per frequency.

        Source channel ``c`` publishes ``Re(a_c exp(j 2 pi f t_k))`` at its due ticks.
        With mixed rates the response to one frequency is not one sinusoid (the slow
        instances alias it), but it is periodic in the super-period ``P`` up to the
        factor ``z = exp(j 2 pi f P base)``: the record is
        ``y(t_(nP + p)) = Re(z^n Y[p])``, exact.

        Parameters
        ----------
        freqs_hz : array_like, shape (n_f,)
            Frequencies (Hz).
        phasors : array_like, shape (n_f, m)
            Complex amplitude of every source channel at each frequency (the columns of
            :meth:`input_matrix`).
        refs : sequence of str
            Recorded outputs to return.
        chunk : int
            Frequencies computed together (memory ``~ P r m chunk``).

        Returns
        -------
        ndarray, shape (P, n_f, len(refs)), complex
            ``Y[p]`` per frequency.
        """

        freqs = np.atleast_1d(np.asarray(freqs_hz, float))
        A = np.asarray(phasors, complex).reshape(freqs.size, self.m)
        sel = self.ref_rows(refs)
        active = np.flatnonzero(np.any(A != 0, axis=0))
        base = float(self.lin.plan.timebase.base)
        units, k = [], 0
        for sig, L in self._runs:
            units.append((self._type(sig, L), k))
            k += L
        T, Q, n_top, scale = self.period_schur()
        zT, diag = -T, np.diag(T).copy()
        out = np.zeros((self.P, freqs.size, sel.size), complex)
        for c0 in range(0, freqs.size, chunk):
            f = freqs[c0:c0 + chunk]
            a = A[c0:c0 + chunk][:, active]                           # (n_c, m_a)
            wv = 2 * np.pi * f * base                                  # rad per tick
            forcing = []
            for t, start in units:
                E = np.exp(1j * np.outer(np.arange(t.L), wv))          # (L, n_c)
                B = E[:, None, :] * a.T[None, :, :]                    # (L, m_a, n_c)
                G = t.G[:, :, active].reshape(self.n_memory, -1)
                forcing.append(np.exp(1j * wv * start) * (G @ B.reshape(-1, f.size)))
            x = np.zeros((self.n_memory, f.size), complex)
            for (t, _), g in zip(units, forcing):
                x = t.ML @ x + g                                       # forced, from rest
            z = np.exp(1j * wv * self.P)
            y = Q.conj().T @ (x / scale[:, None])
            X0 = np.empty_like(y)
            for i in range(f.size):
                if not np.any(a[i]):   # nothing drives (a wheel at rest): no solve at z = 1
                    X0[:, i] = 0.0
                    continue
                np.fill_diagonal(zT, z[i] - diag)                      # z I - T
                X0[:, i] = _solve_deflated(zT, y[:, i], n_top)
            x = (Q @ X0) * scale[:, None]
            for (t, start), g in zip(units, forcing):
                live = np.searchsorted(t.live, sel)
                present = (live < t.live.size) & (t.live[np.minimum(live, t.live.size - 1)]
                                                  == sel)
                rows = live[present]
                O = t.O.reshape(t.L, t.live.size, -1)[:, rows].reshape(t.L * rows.size, -1)
                Yq = (O @ x).reshape(t.L, rows.size, f.size)          # (L, r, n_c)
                if active.size:
                    h = t.h[:, rows][:, :, active]                     # (L, r, m_a)
                    E = np.exp(-1j * np.outer(np.arange(t.L), wv))     # (L, n_c)
                    B = E[:, None, :] * a.T[None, :, :]                # (L, m_a, n_c)
                    conv = np.cumsum(h @ B, axis=0)                    # (L, r, n_c)
                    phase = np.exp(1j * np.outer(start + np.arange(t.L), wv))   # (L, n_c)
                    Yq = Yq + phase[:, None, :] * conv
                Y = np.zeros((t.L, f.size, sel.size), complex)
                Y[:, :, present] = Yq.transpose(0, 2, 1)
                out[start:start + t.L, c0:c0 + chunk] = Y
                x = t.ML @ x + g
        return out


#: An eigenvalue of the super-period map within this of 1 is a unit eigenvalue.
_UNIT_EIG_TOL = 1e-6
#: Singular values of the unit block below this fraction of its largest are null.
_UNIT_RCOND = 1e-8


def _solve_deflated(A: np.ndarray, b: np.ndarray, n_top: int) -> np.ndarray:
    """Solve the upper-triangular ``A x = b`` whose trailing block (from ``n_top``) holds
    the unit eigenvalues: that block by least squares (minimum norm, singular values
    below ``_UNIT_RCOND`` of its largest dropped), then the leading block by back
    substitution with the trailing solution moved to the right-hand side."""
    import scipy.linalg as la

    x = np.empty_like(b)
    if n_top < A.shape[0]:
        x[n_top:] = la.lstsq(A[n_top:, n_top:], b[n_top:], cond=_UNIT_RCOND,
                             check_finite=False)[0]
        rhs = b[:n_top] - A[:n_top, n_top:] @ x[n_top:]
    else:
        rhs = b
    if n_top:
        x[:n_top] = la.solve_triangular(A[:n_top, :n_top], rhs, check_finite=False)
    return x


def balance(A: np.ndarray):
    """Exact power-of-two diagonal balancing: ``(D^-1 A D, diag(D))``.

    The memory state of a loop mixes metres, volts and strains; without it a Schur form
    or an eigenvalue of the loop loses digits to the spread of scales.  A state whose row
    or column of ``A`` is zero up to round-off (a source's held output, written afresh
    each period and never carried over) cannot be balanced: the iteration drives its
    scale to 1e-50 or so, which a vector with that state non-zero does not survive, so
    it keeps scale 1.
    """
    import scipy.linalg as la

    with np.errstate(invalid="ignore"):   # scipy casts its unused permutation
        Ab, T = la.matrix_balance(A, permute=False)
    d = np.diag(T).copy()
    # zero up to round-off of the products that made A (1e-53 against 3 seen)
    tiny = np.finfo(float).eps ** 2 * np.abs(A).max()
    idle = (np.abs(A).max(axis=0) <= tiny) | (np.abs(A).max(axis=1) <= tiny)
    if np.any(idle & (d != 1.0)):
        d[idle] = 1.0
        Ab = A / d[:, None] * d[None, :]      # powers of two: exact
    return Ab, d


def _causal_conv(h: np.ndarray, w: np.ndarray, Hf=None) -> np.ndarray:
    """``y[u, q] = sum_{l <= q} h[q - l] w[u, l]`` for every run ``u``, by FFT.

    Parameters
    ----------
    h : ndarray, shape (L, r, m)
    w : ndarray, shape (n_u, L, m)

    Returns
    -------
    ndarray, shape (n_u, L, r)
    """
    L = h.shape[0]
    if L <= 8:   # short runs: the direct sum is cheaper
        y = np.zeros((w.shape[0], L, h.shape[1]))
        for q in range(L):
            y[:, q] = np.einsum("lrm,ulm->ur", h[q::-1], w[:, :q + 1])
        return y
    n = _fft_length(L)
    if Hf is None:
        Hf = sfft.rfft(h, n, axis=0)                # (f, r, m)
    Wf = sfft.rfft(w, n, axis=1, workers=-1)        # (u, f, m)
    if Wf.shape[2] == 1:
        Yf = Wf * Hf[None, :, :, 0]
    else:
        Yf = np.einsum("frm,ufm->ufr", Hf, Wf, optimize=True)
    return sfft.irfft(Yf, n, axis=1, workers=-1)[:, :L]


def _fft_length(L: int) -> int:
    """A fast FFT length for a linear convolution of two ``L``-long sequences."""
    return sfft.next_fast_len(2 * L - 1, real=True)
