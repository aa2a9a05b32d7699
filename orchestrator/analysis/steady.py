"""Periodic steady states of a compiled loop under harmonic sources.

:class:`SteadyState` holds what :class:`~orchestrator.analysis.fast.FastResponse` does
for lines (wheels, cryocoolers, choppers): the loop's map over one super-period, its
sorted Schur form (kept: a second sweep on the loop reuses it), and the steady state of
every frequency at once from it, exact with mixed rates.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SteadyState", "balance", "loop_eigenvalues"]


class SteadyState:
    """Steady-state methods of :class:`~orchestrator.analysis.fast.FastResponse` (which
    provides the run types, the super-period and the recorded rows)."""

    def period_map(self) -> np.ndarray:
        """The memory state's map over one super-period, ``(n_memory, n_memory)``."""
        Phi = first = None
        for sig, L in self._runs:   # the first run's map starts it: no product with I
            ML = self._type(sig, L).ML
            if Phi is None:
                Phi = first = ML
            else:   # a structured map (a tick's form, a block power): at its own cost
                Phi = ML @ Phi
        return np.array(Phi) if Phi is first else Phi   # never a run's own map

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
            # the real Schur form, sorted, then made complex (twice the speed of a
            # complex Schur form of the real map; the same ordering)
            T, Q, k_top = la.schur(Phi_b, output="real",
                                   sort=lambda x, y: abs(complex(x, y) - 1.0) > _UNIT_EIG_TOL)
            T, Q = la.rsf2csf(T, Q)
            self._schur = (T, Q, int(k_top), scale)
        return self._schur

    def steady_state(self, freqs_hz, phasors, refs, chunk: int = 256) -> np.ndarray:
        """Periodic steady state of ``refs`` under harmonic sources, one per frequency.

        Source channel ``c`` publishes ``Re(a_c exp(j 2 pi f t_k))`` at its due ticks.
        With mixed rates the response to one frequency is not one sinusoid (the slow
        instances alias it), but it is periodic in the super-period ``P`` up to the
        factor ``z = exp(j 2 pi f P base)``: the record is
        ``y(t_(nP + p)) = Re(z^n Y[p])``, exact.  A loop whose ticks are all alike (one
        run over the super-period: every instance due at every tick) is time-invariant:
        there ``Y[p] = exp(j 2 pi f p base) Y[0]``, and only ``Y[0]`` is computed.

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
        time_invariant = len(self._runs) == 1 and self._runs[0][1] == self.P
        out = np.zeros((self.P, freqs.size, sel.size), complex)
        for c0 in range(0, freqs.size, chunk):
            f = freqs[c0:c0 + chunk]
            a = A[c0:c0 + chunk][:, active]                           # (n_c, m_a)
            wv = 2 * np.pi * f * base                                  # rad per tick
            forcing = []
            for t, start in units:
                E = np.exp(1j * np.outer(np.arange(t.L), wv))          # (L, n_c)
                B = E[:, None, :] * a.T[None, :, :]                    # (L, m_a, n_c)
                G = self._columns(t, active)[0].reshape(self.n_memory, -1)
                forcing.append(np.exp(1j * wv * start) * _rc(G, B.reshape(-1, f.size)))
            x = forcing[0]                                             # forced, from rest
            for (t, _), g in zip(units[1:], forcing[1:]):
                x = _rc(t.ML, x) + g
            z = np.exp(1j * wv * self.P)
            y = Q.conj().T @ (x / scale[:, None])
            X0 = np.zeros_like(y)
            on = np.flatnonzero(np.any(a != 0, axis=1))   # a wheel at rest: no solve at z = 1
            if on.size:
                X0[:, on] = _solve_shifted(T, z[on], y[:, on], n_top)   # (z I - T) X0 = y
            x = np.ascontiguousarray((Q @ X0) * scale[:, None])
            for u, ((t, start), g) in enumerate(zip(units, forcing)):
                live = np.searchsorted(t.live, sel)
                present = (live < t.live.size) & (t.live[np.minimum(live, t.live.size - 1)]
                                                  == sel)
                rows = live[present]
                if time_invariant:   # Y[p] = exp(j w p) Y[0]
                    Y0 = np.zeros((f.size, sel.size), complex)
                    Y0[:, present] = (_rc(self._rows(t, rows)[:rows.size], x).T
                                      + (a @ t.D[rows][:, active].T if active.size else 0))
                    spin = np.exp(1j * np.outer(np.arange(self.P), wv))       # (P, n_c)
                    out[:, c0:c0 + chunk] = spin[:, :, None] * Y0[None]
                    break
                O = self._rows(t, rows)
                Yq = _rc(O, x).reshape(t.L, rows.size, f.size)        # (L, r, n_c)
                if active.size:
                    h = self._columns(t, active)[1][:, rows]          # (L, r, m_a)
                    E = np.exp(-1j * np.outer(np.arange(t.L), wv))     # (L, n_c)
                    B = E[:, None, :] * a.T[None, :, :]                # (L, m_a, n_c)
                    conv = np.cumsum(h @ B, axis=0)                    # (L, r, n_c)
                    phase = np.exp(1j * np.outer(start + np.arange(t.L), wv))   # (L, n_c)
                    Yq = Yq + phase[:, None, :] * conv
                if present.all():
                    out[start:start + t.L, c0:c0 + chunk] = Yq.transpose(0, 2, 1)
                else:
                    Y = np.zeros((t.L, f.size, sel.size), complex)
                    Y[:, :, present] = Yq.transpose(0, 2, 1)
                    out[start:start + t.L, c0:c0 + chunk] = Y
                if u + 1 < len(units):   # the last run's end state is not needed
                    x = _rc(t.ML, x) + g
        return out


def _rc(A: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``A @ X`` for a real ``A`` and a complex ``X``: one real product on the interleaved
    real and imaginary parts (half the work of a complex product, no complex copy of
    ``A``)."""
    X = np.ascontiguousarray(X, complex)
    n, k = X.shape
    return (A @ X.view(float).reshape(n, 2 * k)).view(complex).reshape(A.shape[0], k)


#: An eigenvalue of the super-period map within this of 1 is a unit eigenvalue.
_UNIT_EIG_TOL = 1e-6
#: Singular values of the unit block below this fraction of its largest are null.
_UNIT_RCOND = 1e-8


#: Rows of a back-substitution block (the rest of the triangle is one product per block).
_BLOCK_ROWS = 32


def _solve_shifted(T: np.ndarray, z: np.ndarray, Y: np.ndarray, n_top: int) -> np.ndarray:
    """Solve ``(z_j I - T) x_j = y_j`` for every column ``j``, ``T`` upper triangular with
    its unit eigenvalues from ``n_top`` on (:meth:`FastResponse.period_schur`).

    The trailing block by least squares (minimum norm, singular values below
    ``_UNIT_RCOND`` of the largest dropped, one SVD per column, all at once), then the
    leading block by back substitution for every column together: blocks of
    ``_BLOCK_ROWS`` rows, each updated by one product with the solved rows below it.

    Parameters
    ----------
    T : ndarray, shape (n, n), complex
    z : ndarray, shape (n_f,), complex
    Y : ndarray, shape (n, n_f), complex

    Returns
    -------
    ndarray, shape (n, n_f), complex
    """
    n = T.shape[0]
    X = np.empty(Y.shape, complex)
    R = Y.astype(complex, copy=True)
    if n_top < n:
        A = -T[n_top:, n_top:][None] + np.eye(n - n_top)[None] * z[:, None, None]
        U, sv, Vh = np.linalg.svd(A)                              # (n_f, u, u), (n_f, u)
        keep = sv > _UNIT_RCOND * sv[:, :1]
        c = np.einsum("fji,jf->fi", U.conj(), R[n_top:])         # U^H y
        c = np.where(keep, c / np.where(keep, sv, 1.0), 0.0)
        X[n_top:] = np.einsum("fji,fj->if", Vh.conj(), c)        # V c
        R[:n_top] += T[:n_top, n_top:] @ X[n_top:]
    diag = np.diag(T)
    for i1 in range(n_top, 0, -_BLOCK_ROWS):
        i0 = max(0, i1 - _BLOCK_ROWS)
        if i1 < n_top:
            R[i0:i1] += T[i0:i1, i1:n_top] @ X[i1:n_top]
        for i in range(i1 - 1, i0 - 1, -1):
            r = R[i] + T[i, i + 1:i1] @ X[i + 1:i1] if i + 1 < i1 else R[i]
            X[i] = r / (z - diag[i])
    return X


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
    idle = _idle(A)
    if np.any(idle & (d != 1.0)):
        d[idle] = 1.0
        Ab = A / d[:, None] * d[None, :]      # powers of two: exact
    return Ab, d


def _idle(A: np.ndarray) -> np.ndarray:
    """The states whose column or row of ``A`` is zero up to round-off of the products
    that made it (1e-53 against 3 seen): ``eps^2`` of its largest entry."""
    tiny = np.finfo(float).eps ** 2 * np.abs(A).max()
    return (np.abs(A).max(axis=0) <= tiny) | (np.abs(A).max(axis=1) <= tiny)


def loop_eigenvalues(A: np.ndarray) -> np.ndarray:
    """The eigenvalues of a loop map, balanced once: by LAPACK inside
    ``numpy.linalg.eigvals`` (a permutation, then power-of-two scaling), after the
    states :func:`balance` keeps at scale 1 (a row or column zero up to round-off) are
    made exactly zero, so that the permutation sets them apart rather than the scaling
    driving them to 1e-50.  ``eigvals(balance(A)[0])`` balances twice: at 500 modes
    :func:`balance` alone took 45 ms of the 380 ms of an isolation-on loop's poles.
    Moving those entries, at most ``eps^2`` of the largest, to zero moves an eigenvalue
    by less than the round-off of the solve itself.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        A loop's map (a super-period map).

    Returns
    -------
    ndarray, shape (n,), complex
    """
    A = np.asarray(A, float)
    idle = _idle(A)
    if idle.any():
        A = A.copy()
        A[idle] = 0.0
        A[:, idle] = 0.0
    return np.linalg.eigvals(A)
