"""The fast path on the structure it is given: modal 2x2 blocks plus low-rank coupling.

A reduced structure steps its modes as independent 2x2 blocks (:mod:`structfmu.discrete`)
and its static Ritz block as one dense block whose damping is proportional (so one fixed
orthogonal rotation splits it into 2x2 blocks too).  Everything else of a closed loop
(amplifiers, controllers, ACS, held outputs, the accelerometer filter) is a few states
that read the structure through its outputs and write it through its inputs.  In the
basis ``x = Q x~`` (the modes' ``(q, v)`` pairs first, Ritz pairs rotated, the other
states after them) every tick map of a loop's memory state is::

    M = blockdiag(2x2 blocks) + [Gamma; 0] Lu + [0; I] MR  =  Bd + U W

``Gamma`` (pair states x structure inputs) the ZOH input rows of the modes, ``Lu`` the
structure's held inputs after the tick as a function of the memory state (what the
master sets from the other instances' outputs), ``MR`` the rows of the other states.  A
product with ``M`` costs ``4 n_pairs`` for the blocks plus ``(n_in + n_rest) s`` for the
coupling instead of ``s^2``.

:class:`ModalLoop` finds this form once for a compiled nominal loop
(:class:`~orchestrator.analysis.fast.FastResponse`) and checks it against the loop's own
tick maps.  :meth:`ModalLoop.sample` is a Monte Carlo sample's loop: its structure block
(perturbed modal frequencies and damping) changes only the modes' 2x2 blocks and input
rows and the filter rows, which are patched into the nominal form; nothing of the loop
is relinearised.  The :class:`StructuredResponse` it returns is a ``FastResponse``
whose run types (``M^L``, the row Krylov products ``C M^q``, the column Krylov products
``M^q N`` and Markov parameters) come from block-wise recursions: ``M^L`` of the pairs the
coupling never reads is their own 2x2 power, the rest by recursion or, where the
coupling is dense, by squaring a power of structured products or from the coupling's
own rows carried along (the cheapest, counted in flops).  Its records equal the dense
engine's to round-off (tested on the truss and the EOS loops).
"""

from __future__ import annotations

import numpy as np

from ._pairs import pair_left, pair_right
from .blocks import AnalysisError
from .fast import FastResponse, _RunType
from .fastparts import (_add_pairs, _BlockPower, _coupled_power, _pair_power,
                        _power_chain, _tick_map)

__all__ = ["ModalLoop", "StructuredResponse", "StructureRefused", "modal_loop", "respond"]

# the structured form must rebuild the loop's own tick maps to this fraction of their
# largest entry (the Ritz rotation leaves round-off off its 2x2 blocks: 2e-15 on EOS)
_FORM_TOL = 1e-11
# proportional damping of the Ritz block: V^T D V diagonal to this fraction
_PROPORTIONAL_TOL = 1e-10


# the ways of M^L in _Form.run, in the order of their costs there
_WAYS = ("recursion", "squaring", "coupling")


class StructureRefused(AnalysisError):
    """A loop whose tick maps are not modal blocks plus low-rank coupling."""


class _Form:
    """One tick map as ``Bd + U W`` in the basis ``x = Q x~`` (see the module docstring).

    Attributes: ``a`` (n_pairs, 2, 2) the blocks, ``gamma`` (2 n_pairs, k_in) the pairs'
    input rows, ``W`` (k_in + n_rest, s) the coupling rows (``Lu`` over ``MR``), ``N``
    (s, m) the input columns, ``n_p`` the pair states."""

    __slots__ = ("a", "gamma", "W", "N", "n_p", "k_in", "_split", "_read")
    # ``ndarray @ form`` is the form's left product (numpy defers to __rmatmul__)
    __array_ufunc__ = None

    def __init__(self, a, gamma, W, N):
        self.a, self.gamma, self.W, self.N = a, gamma, W, N
        self.n_p = 2 * a.shape[0]
        self.k_in = gamma.shape[1]
        # W in the two parts left and right multiply (_parts)
        rows = np.flatnonzero(np.any(W[:, :self.n_p] != 0.0, axis=1))
        self._split = (rows, np.ascontiguousarray(W[rows, :self.n_p]),
                       np.ascontiguousarray(W[:, self.n_p:]))
        # the pairs some coupling row reads
        self._read = np.any(W[:, :self.n_p] != 0.0, axis=0).reshape(-1, 2).any(axis=1)

    @property
    def s(self) -> int:
        return self.W.shape[1]

    def dense(self) -> np.ndarray:
        """The tick map ``(s, s)`` itself."""
        n_p, s = self.n_p, self.s
        M = np.zeros((s, s))
        M[:n_p] = self.gamma @ self.W[:self.k_in]
        M[n_p:] = self.W[self.k_in:]
        _add_pairs(M, self.a)
        return M

    def right(self, X: np.ndarray) -> np.ndarray:
        """``M X`` for ``X`` (s, c) (a matrix, or anything ``numpy.asarray`` makes one)."""
        X = np.asarray(X)
        n_p, c = self.n_p, X.shape[1]
        rows, Wp, rest = self._parts()
        Z = rest @ X[n_p:]
        Z[rows] += Wp @ X[:n_p]
        Y = np.empty((X.shape[0], c))
        pair_right(self.a, X, Y)
        Y[:n_p] += self.gamma @ Z[:self.k_in]
        Y[n_p:] = Z[self.k_in:]
        return Y

    def _parts(self) -> tuple:
        """``W`` in the two parts :meth:`left` and :meth:`right` multiply: the rows that
        read the pairs on the pair columns (with isolation on 60 of the EOS loop's 144:
        its 99-tick run's 98 row products 23 ms instead of 30 ms), and the other
        columns.  Exact: only zero terms are left out.  (Those columns as a sparse
        matrix, 1215 of 18144 entries non-zero, took 19 ms, but a Monte Carlo worker
        then held 1.2 GB instead of 0.88 GB.)"""
        return self._split

    def left(self, O: np.ndarray) -> np.ndarray:
        """``O M`` for ``O`` (r, s)."""
        n_p, a = self.n_p, self.a
        rows, Wp, rest = self._parts()
        coef = np.empty((O.shape[0], self.W.shape[0]))
        coef[:, :self.k_in] = O[:, :n_p] @ self.gamma
        coef[:, self.k_in:] = O[:, n_p:]
        Y = np.empty((O.shape[0], self.s))
        np.matmul(coef[:, rows], Wp, out=Y[:, :n_p])
        np.matmul(coef, rest, out=Y[:, n_p:])
        pair_left(O, a, Y)
        return Y

    def step_cost(self) -> float:
        """Flops of one product with one vector, counting every coupling row on every
        column: more than :meth:`right` and :meth:`left` multiply (they leave out the
        rows that do not read the pairs on the pair columns, :meth:`_parts`), the count
        by which :meth:`run` chooses how to form ``M^L``.  With the products' own count
        it would choose the same way for the EOS loop with isolation on at 70, 280 and
        500 modes, and at 70 modes a chain no faster (``M^99`` 13.7 against 13.9 ms)."""
        return 2.0 * self.W.size + 2.0 * self.gamma.size + 6.0 * self.n_p

    def power(self, L: int) -> np.ndarray:
        """``M^L`` (s, s): the pairs no coupling row reads by their own 2x2 power, the
        others by ``L`` products, or all by squaring where that costs fewer flops."""
        return self.run(L, np.zeros((0, self.s)), np.zeros((self.s, 0)))[0]

    def power_costs(self, L: int, step: float | None = None) -> tuple:
        """Flops of ``M^L`` each way of :meth:`run` (``_WAYS``: the recursion of the
        columns the coupling reads, squaring, the coupling's rows), and the squaring's
        chain (:func:`~.fastparts._power_chain`); ``step`` the flops of a product with
        one vector (default :meth:`step_cost`, the count :meth:`run` chooses by)."""
        s, n_p = self.s, self.n_p
        step = self.step_cost() if step is None else step
        chain, squaring = _power_chain(L, 2.0 * s ** 3, s * step)
        return ((2 * int(self._read.sum()) + s - n_p) * L * step, squaring,
                (L - 1) * self.W.shape[0] * step + 2.0 * n_p * L * self.k_in * s), chain

    def run(self, L: int, C: np.ndarray, N: np.ndarray) -> tuple:
        """``M^L``, the rows ``C M^q`` (L, r, s) and the columns ``M^q N`` (s, L, c),
        ``q < L``, in one recursion over the run's ticks.

        ``M^L`` the cheapest in flops of: the pairs no coupling row reads by their own
        2x2 power and the other columns by ``L`` products; squaring a power of
        structured products (:func:`~.fastparts._power_chain`); or the coupling's rows
        carried along the recursion (:func:`~.fastparts._coupled_power`, a large model
        with a dense coupling: 500 modes with isolation on).  A single tick is the form
        itself (it multiplies as ``M``)."""
        s, n_p, read = self.s, self.n_p, self._read
        cols = np.concatenate([np.flatnonzero(np.repeat(read, 2)), np.arange(n_p, s)])
        costs, chain = self.power_costs(L)
        how = _WAYS[int(np.argmin(costs))] if L > 1 else "form"
        k = cols.size if how == "recursion" else 0
        X = np.zeros((s, k + N.shape[1]))
        X[cols[:k], np.arange(k)] = 1.0
        X[:, k:] = N
        r = C.shape[0]
        O = np.empty((L, r, s))
        K = np.empty((s, L, N.shape[1]))
        O[0], K[:, 0] = C, N
        if how == "coupling":   # the coupling's rows W M^q along with C M^q
            R, Zu = np.vstack([C, self.W]), np.empty((L, self.k_in, s))
            Zu[0] = self.W[:self.k_in]
        for q in range(1, L + 1):
            if q < L and how == "coupling":
                R = self.left(R)
                O[q], Zu[q] = R[:r], R[r:r + self.k_in]
            elif q < L and r:
                O[q] = self.left(O[q - 1])
            if X.shape[1] and (k or q < L):
                X = self.right(X)
                if q < L:
                    K[:, q] = X[:, k:]
        if how == "form":
            ML = self
        elif how == "coupling":
            ML = _coupled_power(self.a, self.gamma, Zu, R[r + self.k_in:])
        elif how == "squaring" and chain is None:   # left to right, by L's digits
            ML = self.dense()
            for bit in bin(L)[3:]:
                ML = ML @ ML
                if bit == "1":
                    ML = self.right(ML)
        elif how == "squaring":   # M^m by structured products, squared j times, M^e
            m, j, e = chain
            ML = self.dense()
            for _ in range(m - 1):
                ML = self.right(ML)
            for _ in range(j):
                ML = ML @ ML
            for _ in range(e):
                ML = self.right(ML)
        else:
            free = np.flatnonzero(~read)
            ML = _BlockPower(s, 2 * free, _pair_power(self.a[free], L), cols, X[:, :k])
            ML = ML if 2 * cols.size <= s else ML.toarray()
        return ML, O, K

    __matmul__ = right
    __rmatmul__ = left

    def toarray(self) -> np.ndarray:
        """The tick map ``(s, s)`` (as :meth:`dense`)."""
        return self.dense()

    copy = toarray

    @property
    def nbytes(self) -> int:
        return self.a.nbytes + self.gamma.nbytes + self.W.nbytes

    @property
    def shape(self) -> tuple:
        return (self.s, self.s)

    def __array__(self, dtype=None, copy=None):
        return self.dense() if dtype is None else self.dense().astype(dtype)


class ModalLoop:
    """A compiled loop's tick maps as modal 2x2 blocks plus low-rank coupling.

    Parameters
    ----------
    fr : FastResponse
        The nominal compiled loop (its memory state, runs and records).

    Raises
    ------
    StructureRefused
        With one sentence when the loop has not one reduced structure, or its tick maps
        are not that form (checked against them).
    """

    def __init__(self, fr: FastResponse):
        self.fr = fr
        self.channels = set()   # source channels samples of this loop drove
        lin = fr.lin
        names = [n for n, b in lin.blocks.items()
                 if b.kind == "structure" and b.model is not None]
        if len(names) != 1:
            raise StructureRefused(f"the structured engine needs one reduced structure in "
                                   f"the loop; it has {len(names)}: the dense engine runs it")
        self.name = name = names[0]
        block = lin.blocks[name]
        model = block.model
        self.block = block
        sx, su, _ = lin.slots[name]
        S = fr._S
        col = {int(j): c for c, j in enumerate(S)}
        n_m, n_r = model.n_modes, model.n_ritz
        at = [col.get(sx.start + i) for i in range(block.n)]
        pairs, rot = [], []          # pairs: (col q, col v) per modal mode
        for i in range(n_m):
            if at[i] is not None and at[n_m + i] is not None:
                pairs.append((at[i], at[n_m + i]))
        ritz = list(range(2 * n_m, 2 * n_m + 2 * n_r))
        V = None
        if n_r and all(at[i] is not None for i in ritz):
            w, V = np.linalg.eigh(model.K_oo)
            Dd = V.T @ model.D_oo @ V
            off = np.abs(Dd - np.diag(np.diag(Dd))).max()
            if off > _PROPORTIONAL_TOL * max(np.abs(np.diag(Dd)).max(), 1e-300):
                V = None
        used = {c for p in pairs for c in p}
        if V is not None:
            used |= {at[i] for i in ritz}
        rest = [c for c in range(S.size) if c not in used]
        s, n_p = S.size, 2 * len(pairs) + (2 * n_r if V is not None else 0)
        Q = np.zeros((s, s))
        for p, (cq, cv) in enumerate(pairs):
            Q[cq, 2 * p], Q[cv, 2 * p + 1] = 1.0, 1.0
        if V is not None:
            o = 2 * len(pairs)
            qo = np.array([at[i] for i in ritz[:n_r]])
            vo = np.array([at[i] for i in ritz[n_r:]])
            Q[np.ix_(qo, o + 2 * np.arange(n_r))] = V
            Q[np.ix_(vo, o + 2 * np.arange(n_r) + 1)] = V
        Q[rest, n_p + np.arange(len(rest))] = 1.0
        self.Q, self.n_p, self.rest = Q, n_p, np.asarray(rest, int)
        self.n_modes_paired = len(pairs)
        self.pairs = np.asarray(pairs, int).reshape(-1, 2)
        self.ritz_V = V
        # the structure's own rows among the memory state: in the basis, the pairs and
        # the structure states left among the others (the filter, a half-kept mode)
        local = {c: i for i, c in enumerate(at) if c is not None}
        self._struct_rest = np.array([j for j, c in enumerate(rest) if c in local], int)
        self._struct_rest_state = np.array([local[rest[j]] for j in self._struct_rest], int)
        self._struct_cols = np.array(sorted(local), int)            # memory columns
        self._struct_state = np.array([local[c] for c in self._struct_cols], int)
        # per signature: the nominal tick map and the structure's inputs after the tick
        first = {}
        for k in range(fr.P):
            first.setdefault(fr._signature(k), k)
        order = list(lin.blocks)
        self._due = {sig: bool(sig[order.index(name)]) for sig in first}
        self._base = {}
        worst = 0.0
        for sig, k in first.items():
            Mf, Nf = _tick_map(fr, k, S)
            Lu, Nu = Mf[su], Nf[su]
            live = np.flatnonzero(np.any(Lu != 0.0, axis=1))      # the coupling
            drive = np.flatnonzero(np.any(Nu != 0.0, axis=1))     # the sources
            Mt = Q.T @ Mf[S] @ Q
            base = {"Mt": Mt, "Nt": Q.T @ Nf[S], "Lu": Lu[live] @ Q, "Nu": Nu[drive],
                    "live": live, "drive": drive, "C": fr._maps[sig][2] @ Q}
            self._base[sig] = base
            form = self._form(sig, block)
            err = np.abs(form.dense() - Mt).max() / max(np.abs(Mt).max(), 1e-300)
            worst = max(worst, err)
        self.form_error = worst
        if worst > _FORM_TOL:
            raise StructureRefused(
                f"the tick maps of the loop are not modal 2x2 blocks plus coupling through "
                f"{name!r}'s inputs (rebuilt to {worst:.1e} of their largest entry): the "
                "dense engine runs it")

    # ------------------------------------------------------------------ forms
    def _form(self, sig, block) -> _Form:
        """The structured tick map of signature ``sig`` with the structure ``block``."""
        base, Q, n_p = self._base[sig], self.Q, self.n_p
        Mt, live = base["Mt"], base["live"]
        k_in = live.size
        rest = self.rest
        W = np.empty((k_in + rest.size, Mt.shape[0]))
        W[:k_in] = base["Lu"]
        W[k_in:] = Mt[n_p:]
        N = base["Nt"].copy()
        n_pairs = n_p // 2
        a = np.zeros((n_pairs, 2, 2))
        gamma = np.zeros((n_p, k_in))
        if not self._due[sig]:   # the structure holds: identity on its pairs
            a[:] = np.eye(2)
            N[:n_p] = 0.0
            return _Form(a, gamma, W, N)
        A, B = block.A, block.B
        n_m, nm = self.n_modes_paired, block.model.n_modes
        # the modes: a11 a12 / a21 a22 from the diagonals of the step matrix
        qi = self._paired_modes()
        vi = nm + qi
        a[:n_m, 0, 0], a[:n_m, 0, 1] = A[qi, qi], A[qi, vi]
        a[:n_m, 1, 0], a[:n_m, 1, 1] = A[vi, qi], A[vi, vi]
        gamma[0:2 * n_m:2] = B[qi][:, live]
        gamma[1:2 * n_m:2] = B[vi][:, live]
        if self.ritz_V is not None:   # the same for every sample (checked)
            a[n_m:], gamma[2 * n_m:] = self._ritz(sig)
        drive = base["drive"]
        N[0:2 * n_m:2] = B[qi][:, drive] @ base["Nu"]
        N[1:2 * n_m:2] = B[vi][:, drive] @ base["Nu"]
        # structure states among the others (the filter): their rows patched
        if self._struct_rest.size:
            rows = self._struct_rest_state
            cols = self._struct_cols
            R = np.zeros((rows.size, Q.shape[0]))
            R[:, cols] = A[rows][:, self._struct_state]
            W[k_in + self._struct_rest] = R @ Q + B[rows][:, live] @ base["Lu"]
            N[n_p + self._struct_rest] = B[rows][:, drive] @ base["Nu"]
        return _Form(a, gamma, W, N)

    def _ritz(self, sig) -> tuple:
        """The rotated Ritz block's 2x2 blocks and input rows (kept per signature)."""
        got = self._base[sig].get("ritz")
        if got is None:
            A, B, live = self.block.A, self.block.B, self._base[sig]["live"]
            V, nm, nr = self.ritz_V, self.block.model.n_modes, self.block.model.n_ritz
            o = 2 * nm
            Phi = A[o:o + 2 * nr, o:o + 2 * nr]
            R = np.empty((nr, 2, 2))
            for i, rows in enumerate((Phi[:nr], Phi[nr:])):   # V^T Phi_ij V, diagonal
                for j in range(2):
                    R[:, i, j] = np.einsum("lk,lm,mk->k", V, rows[:, j * nr:(j + 1) * nr], V)
            Bo = B[o:o + 2 * nr][:, live]
            g = np.empty((2 * nr, live.size))
            g[0::2], g[1::2] = V.T @ Bo[:nr], V.T @ Bo[nr:]
            got = self._base[sig]["ritz"] = (R, g)
        return got

    def _paired_modes(self) -> np.ndarray:
        """The modal modes kept as pairs (both their states in the memory state)."""
        if not hasattr(self, "_modes"):
            sx = self.fr.lin.slots[self.name][0]
            S = self.fr._S
            self._modes = np.asarray(S[self.pairs[:, 0]] - sx.start, int)
        return self._modes

    def sample(self, block, lin=None) -> "StructuredResponse":
        """The loop with the structure ``block`` (a sample's perturbed modes).

        Parameters
        ----------
        block : Block
            :func:`~orchestrator.analysis.blocks.structure_block` of the perturbed
            model: the same outputs (``C``, ``D``) and Ritz block as the nominal one
            (the Ritz block to ``_FORM_TOL`` of its largest entry).
        lin : LinearScenario, optional
            The sample's loop (default the nominal one with ``block``).

        Returns
        -------
        StructuredResponse

        Raises
        ------
        StructureRefused
            When ``block`` changes more than the modes (its output rows, its Ritz block).
        """
        b0 = self.block
        used = self._used_outputs()
        if (block.A.shape != b0.A.shape or not np.array_equal(block.C[used], b0.C[used])
                or not np.array_equal(block.D[used], b0.D[used])):
            raise StructureRefused(f"the sample's structure {block.name!r} changes its "
                                   "output rows: the dense engine runs it")
        nm, nr = b0.model.n_modes, b0.model.n_ritz
        o = slice(2 * nm, 2 * nm + 2 * nr)
        # the same to round-off: BLAS threads change the last bits of its step matrices
        near = lambda x, y: np.abs(x - y).max() <= _FORM_TOL * np.abs(y).max()  # noqa: E731
        if nr and not (near(block.A[o, o], b0.A[o, o]) and near(block.B[o], b0.B[o])):
            raise StructureRefused(f"the sample's structure {block.name!r} changes its "
                                   "static Ritz block: the dense engine runs it")
        lin = self.fr.lin.with_block(block) if lin is None else lin
        forms = {sig: self._form(sig, block) for sig in self._base}
        return StructuredResponse(self, lin, forms)

    def _used_outputs(self) -> np.ndarray:
        """The structure's outputs the loop reads or records (the others may change)."""
        if not hasattr(self, "_used"):
            lin, fr = self.fr.lin, self.fr
            names = {lin.blocks[self.name].outputs[i] for _, _, src, i, _ in lin._conns
                     if src == self.name}
            names |= {r.partition(".")[2] for r in list(fr.refs) + [c[0] for c in fr._checks]
                      if r.partition(".")[0] == self.name}
            self._used = np.array([i for i, o in enumerate(self.block.outputs) if o in names],
                                  int)
        return self._used

    def nominal(self) -> "StructuredResponse":
        """The nominal loop in the structured form."""
        return self.sample(self.block, self.fr.lin)


class StructuredResponse(FastResponse):
    """A :class:`FastResponse` whose run types come from the structured tick maps.

    Built by :meth:`ModalLoop.sample`; its memory state is in the loop's basis ``x~``
    (records, limits and poles are those of the dense loop)."""

    def __init__(self, loop: ModalLoop, lin, forms: dict):   # noqa: D107 (no super)
        base = loop.fr
        for key in ("refs", "_checks", "_zero", "_computed", "_check_col", "inputs", "_r",
                    "_inner", "_inner_cols",
                    "_in_off", "m", "P", "_runs", "_S", "n_memory"):
            setattr(self, key, getattr(base, key))
        self.lin = lin
        self.loop = loop
        self._forms = forms
        self._maps = _LazyMaps(self)
        self._types = {}
        self._form_of = {}
        self._schur = None
        self._kernels = {}

    def _type(self, sig, L: int) -> _RunType:
        key = (sig, L)
        t = self._types.get(key)
        if t is not None:
            return t
        f = self._forms[sig]
        C = self.loop._base[sig]["C"]
        D = self._feedthrough(sig)
        live = np.flatnonzero(np.any(C != 0, axis=1) | np.any(D != 0, axis=1))
        # the channels the loop's records drove before (a Monte Carlo's next sample
        # drives the same ones): their columns in the same recursion
        ch = sorted(self.loop.channels)
        ML, O, K = f.run(L, C[live], f.N[:, ch])
        t = _RunType(L, ML, O.reshape(L * live.size, f.s), live, None, f.N,
                     np.ascontiguousarray(D[live]), {}, ())
        if ch:
            self._store_columns(t, ch, K)
        self._types[key] = t
        self._form_of[id(t)] = f   # the run types live as long as the loop
        return t

    def _feedthrough(self, sig) -> np.ndarray:
        """Feedthrough of the recorded rows for the ticks of ``sig``."""
        return self.loop.fr._maps[sig][3]

    def _column_krylov(self, t: _RunType, miss) -> np.ndarray:
        """``M^q N`` of the channels ``miss``, ``(s, L, c)``: block-wise recursion."""
        self.loop.channels.update(miss)
        f = self._form_of[id(t)]
        return f.run(t.L, np.zeros((0, f.s)), t.N[:, miss])[2]


class _LazyMaps(dict):
    """``_maps`` of a structured loop, ``(M, N, C, D)`` per signature in its basis,
    made dense on first use (the run types never need them)."""

    def __init__(self, fr: StructuredResponse):
        super().__init__()
        self._fr = fr

    def __missing__(self, sig):
        f = self._fr._forms[sig]
        got = (f.dense(), f.N, self._fr.loop._base[sig]["C"], self._fr._feedthrough(sig))
        self[sig] = got
        return got


# the structured form is used where one product with it costs at most this fraction of a
# dense one (below, the recursions and the squaring cost the same; above, dense wins)
_PAYS = 0.5


def modal_loop(fr: FastResponse):
    """The structured form of the compiled loop ``fr`` (kept on it), or None.

    Parameters
    ----------
    fr : FastResponse
        A nominal compiled loop.

    Returns
    -------
    ModalLoop or None
        None where the loop is not modal blocks plus low-rank coupling, or where that
        form does not pay; ``fr.structure_reason`` then says why in one sentence.
    """
    if not hasattr(fr, "_modal"):
        fr._modal, fr.structure_reason = None, None
        try:
            loop = ModalLoop(fr)
        except StructureRefused as exc:
            fr.structure_reason = str(exc)
        else:
            ratio = max(f.step_cost() / (2.0 * f.s ** 2)
                        for f in (loop._form(sig, loop.block) for sig in loop._base))
            if ratio > _PAYS:
                fr.structure_reason = (
                    f"the coupling of {loop.name!r} with the rest of the loop is not low "
                    f"rank (a product with the structured map costs {ratio:.0%} of a dense "
                    "one): the dense engine runs it")
            else:
                fr._modal = loop
    return fr._modal


def respond(lin, refs, like: FastResponse) -> FastResponse:
    """A sample of ``like``'s loop: structured where only its structure's modes differ.

    Parameters
    ----------
    lin : LinearScenario
        The sample's loop: ``like``'s with a perturbed structure block
        (:meth:`~orchestrator.analysis.LinearScenario.with_block`), or with other
        changes (a controller's gain), which the dense engine runs.
    refs : sequence of str
        Outputs to record.
    like : FastResponse
        The nominal compiled loop.

    Returns
    -------
    FastResponse
        A :class:`StructuredResponse` (:meth:`ModalLoop.sample`) where the structured
        form applies and pays (:func:`modal_loop`), else ``FastResponse(lin, refs,
        like=like)``: the same records either way, to round-off.
    """
    loop = modal_loop(like)
    if loop is not None and tuple(refs) == like.refs:
        changed = [n for n, b in lin.blocks.items() if b is not like.lin.blocks.get(n)]
        if set(changed) <= {loop.name} and lin.blocks.keys() == like.lin.blocks.keys():
            try:
                return loop.sample(lin.blocks[loop.name], lin)
            except StructureRefused:
                pass
    return FastResponse(lin, refs, like=like)
