"""How many poles of a structured loop lie outside the unit circle, without its dense
eigenvalues: the argument principle on the modes' 2x2 blocks plus a low-rank coupling.

With isolation off, the EOS loop's pairs run free between two ACS ticks (no coupling
row reads them at the 1 kHz ticks), so its super-period map, started at the ACS tick, is

    Psi = M^99 M_acs = D + U' W,   D = blockdiag(a_j^100) (+ 0 on the other states),

with ``W`` the ACS tick's coupling rows and ``U' = M^99 U`` its ``k = k_in + n_rest``
columns (18 on EOS).  Then ``det(zI - Psi) = det(zI - D) f(z)`` with

    f(z) = det(I_k - W (zI - D)^-1 U'),   (zI - A)^-1 = ((z - tr A) I + A) / det(zI - A),

a k-by-k determinant that costs the pairs' count times ``k`` times the rank of the
coupling's pair columns per point.  The poles of ``Psi`` outside ``|z| = rho`` number
``n_D - w``: ``n_D`` the blocks' eigenvalues outside, ``w`` the winding of ``f`` around
0 along the circle (``f(inf) = 1``).  ``f`` is real on the real axis, so the upper half
circle gives ``w``.

The winding is sampled: a grid on the half circle, denser near every block eigenvalue
close to it (the rigid bodies' double poles at 1 sit ``tol`` inside), and every interval
refined until the phase and the log-magnitude at its midpoint follow their neighbours
(a pair of zeros between two points turns the phase by a whole turn and is seen in the
magnitude).  A count that is not certain (the grid does not settle, a point meets a
zero) is None, and so is a loop without this form: its dense eigenvalues decide
(:func:`.sweep.unstable_poles`).  Equal in verdict to the eigenvalues on every tested
sample (``tests/orchestrator/test_structured_poles.py``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .fastparts import _pair_power
from .structured import StructuredResponse

__all__ = ["Split", "period_split", "unstable_count", "winding_count"]

# the half circle's first grid, and the ratio of the grids about the eigenvalues near it
_N0, _RATIO = 64, 2.0
# an interval is accepted when its midpoint's phase is within this of the chord's and
# the whole interval turns less than twice that; and its log-magnitude within _LOG
_PHASE, _LOG = np.pi / 8, 0.3
# more points than this, or an interval this short: not certain
_CAP, _SHORTEST = 20000, 1e-13


class Split(NamedTuple):
    """A super-period map as ``D + U W`` on the states that drive the structure, and the
    map of those that only watch it (:func:`period_split`)."""

    A: np.ndarray         # (n_pairs, 2, 2) the pairs' blocks of D (0 on the other states)
    U: np.ndarray         # (n, k)
    W: np.ndarray         # (k, n)
    n_p: int              # the pair states, first of the n
    states: np.ndarray    # (n,) those n states of the memory state
    watch: np.ndarray     # (n_o, n_o) the map of the others (they read, nothing reads them)


def _driving(forms, s: int, n_p: int, k_in: int) -> np.ndarray:
    """The states that drive the structure's pairs at some tick, the pairs included:
    the closure of what the structure's inputs and those states' own rows read."""
    drive = np.zeros(s, bool)
    drive[:n_p] = True
    while True:
        new = drive.copy()
        for f in forms:
            new |= np.any(f.W[:k_in] != 0.0, axis=0)
            new |= np.any(f.W[k_in:][drive[n_p:]] != 0.0, axis=0)
        if np.array_equal(new, drive):
            return drive
        drive = new


def period_split(fr) -> tuple:
    """The super-period map of a structured loop as ``D + U W``, or why not.

    States that read the structure but drive nothing of it (a filter of an output that
    is only recorded) make the map block triangular: their own map over the period is
    kept apart (``Split.watch``), and the split is of the others.

    Parameters
    ----------
    fr : FastResponse
        A compiled loop; only a :class:`~.structured.StructuredResponse` has the form.

    Returns
    -------
    tuple
        ``(Split, None)``, the map started at the one tick whose coupling reads the
        pairs; or ``(None, reason)``, one sentence.
    """
    if not isinstance(fr, StructuredResponse):
        return None, "the loop is not in its structured form (the dense engine runs it)"
    runs, forms = fr._runs, fr._forms
    f = next(iter(forms.values()))
    s, n_p, k_in = f.s, f.n_p, f.k_in
    drive = _driving(forms.values(), s, n_p, k_in)
    rest = np.flatnonzero(drive[n_p:])
    rows = np.concatenate([np.arange(k_in), k_in + rest])   # of W: what the pairs see
    reads = [bool(forms[sig].W[rows, :n_p].any()) for sig, _ in runs]
    if sum(reads) != 1 or runs[reads.index(True)][1] != 1:
        ticks = sum(L for (_, L), r in zip(runs, reads) if r)
        return None, (f"the coupling reads the structure's modes at {ticks} of the "
                      f"super-period's {sum(L for _, L in runs)} ticks, so its map is not "
                      "their own powers plus one low-rank coupling: the dense eigenvalues "
                      "decide its poles")
    i0 = reads.index(True)
    f = forms[runs[i0][0]]
    states, watch = np.flatnonzero(drive), np.flatnonzero(~drive)
    U = np.zeros((s, rows.size))
    U[:n_p, :k_in] = f.gamma
    U[n_p + rest, k_in + np.arange(rest.size)] = 1.0
    A = f.a
    E = np.zeros((s, watch.size))
    E[watch, np.arange(watch.size)] = 1.0
    Po = f.W[k_in + watch - n_p][:, watch]
    for j in range(1, len(runs)):   # the other runs leave the pairs to their blocks
        sig, L = runs[(i0 + j) % len(runs)]
        ML = fr._type(sig, L).ML
        U = ML @ U
        A = np.matmul(_pair_power(forms[sig].a, L), A)
        if watch.size:
            Po = (ML @ E)[watch] @ Po
    return Split(A, U[states], f.W[rows][:, states], n_p, states, Po), None


class _Coupling:
    """``f(z)`` of ``D + U W`` at many points: the pairs' terms compressed to the rank
    of the coupling's pair columns (the side of lower rank)."""

    def __init__(self, A, U, W, n_p):
        k, n = W.shape[0], A.shape[0]
        self.k = k
        Wp, Up = W[:, :n_p], U[:n_p]
        eps = np.finfo(float).eps
        rank = []
        for side in (Wp, Up):
            sv = np.linalg.svd(side, compute_uv=False)
            rank.append(int(np.sum(sv > sv[0] * eps * max(side.shape))) if sv.size and
                        sv[0] > 0 else 0)
        if rank[0] <= rank[1]:   # Wp = L B
            u, sv, vt = np.linalg.svd(Wp, full_matrices=False)
            self.L, r = u[:, :rank[0]], rank[0]
            Bj = (sv[:r, None] * vt[:r]).reshape(r, n, 2).transpose(1, 0, 2)
            Uj = Up.reshape(n, 2, k)
            X, Y = Bj @ Uj, Bj @ A @ Uj                       # (n, r, k)
            self.left = True
        else:                    # Up = B L
            u, sv, vt = np.linalg.svd(Up, full_matrices=False)
            self.L, r = vt[:rank[1]], rank[1]
            Wj = Wp.reshape(k, n, 2).transpose(1, 0, 2)
            Bj = (u[:, :r] * sv[:r]).reshape(n, 2, r)
            X, Y = Wj @ Bj, Wj @ A @ Bj                       # (n, k, r)
            self.left = False
        self.shape = X.shape[1:]
        keep = np.any(X != 0.0, axis=(1, 2)) | np.any(Y != 0.0, axis=(1, 2))
        size = int(np.prod(self.shape))
        n = int(keep.sum())
        self.XY = np.concatenate([X[keep].reshape(n, size), Y[keep].reshape(n, size)])
        self.tr = A[keep, 0, 0] + A[keep, 1, 1]
        self.det = A[keep, 0, 0] * A[keep, 1, 1] - A[keep, 0, 1] * A[keep, 1, 0]
        self.poles = np.linalg.eigvals(A[keep]).ravel()   # of f near the circle
        self.R0 = W[:, n_p:] @ U[n_p:]

    def point_flops(self) -> float:
        """Flops of :meth:`phase` at one point: the pair terms (real and imaginary
        parts), the compression's product and the complex k-by-k LU."""
        return 4.0 * self.XY.size + 2.0 * self.L.size * self.k + 32.0 / 3.0 * self.k ** 3

    def phase(self, z) -> tuple:
        """Phase and log-magnitude of ``f`` at the points ``z``."""
        zc = z[:, None]
        p = zc * zc - self.tr * zc + self.det
        C = np.concatenate([(zc - self.tr) / p, 1.0 / p], axis=1)
        G = (C.real @ self.XY + 1j * (C.imag @ self.XY)).reshape((z.size,) + self.shape)
        F = (self.L @ G if self.left else G @ self.L) + self.R0 / z[:, None, None]
        sign, logabs = np.linalg.slogdet(np.eye(self.k) - F)
        return np.angle(sign), logabs


def winding_count(A, U, W, n_p, tol: float = 1e-6) -> tuple:
    """Eigenvalues of ``D + U W`` with ``|z| > 1 + tol``, by the argument principle.

    Parameters
    ----------
    A : ndarray, shape (n_pairs, 2, 2)
        The 2x2 blocks of ``D`` on its first ``n_p`` states (the rest of ``D`` is 0).
    U : ndarray, shape (s, k)
    W : ndarray, shape (k, s)
        The coupling.
    n_p : int
        The pair states (``2 n_pairs``).
    tol : float
        Margin above ``|z| = 1`` (-), as :func:`.sweep.unstable_poles`.

    Returns
    -------
    (int or None, int)
        The count (None where the sampled winding is not certain) and the points at
        which ``f`` was evaluated.
    """
    rho = 1.0 + tol
    n_out = int(np.sum(np.abs(np.linalg.eigvals(A)) > rho))
    if W.shape[0] == 0:
        return n_out, 0
    f = _Coupling(A, U, W, n_p)
    h = np.pi / _N0
    near = f.poles[np.abs(rho - np.abs(f.poles)) < h]
    dist = np.abs(rho - np.abs(near))
    th = [np.linspace(0.0, np.pi, _N0 + 1)]
    if near.size:
        if np.any(dist == 0.0):
            return None, 0
        steps = np.ceil(np.log(4.0 * h / dist) / np.log(_RATIO)).astype(int) + 1
        for c, d, n in zip(np.abs(np.angle(near)), dist, steps):
            g = d / 4.0 * _RATIO ** np.arange(n)
            th += [c - g, c + g, [c]]
    th = np.unique(np.clip(np.concatenate(th), 0.0, np.pi))
    ph, la = f.phase(rho * np.exp(1j * th))
    done = np.zeros(th.size - 1, bool)   # interval i (th[i], th[i+1]) accepted
    while not done.all():
        todo = np.flatnonzero(~done)
        if th.size > _CAP or np.any(th[todo + 1] - th[todo] < _SHORTEST) or \
                not np.isfinite(la).all():
            return None, th.size
        mid = (th[todo] + th[todo + 1]) / 2.0
        pm, lm = f.phase(rho * np.exp(1j * mid))
        turn = np.angle(np.exp(1j * (ph[todo + 1] - ph[todo])))
        half = np.angle(np.exp(1j * (pm - ph[todo])))
        ok = ((np.abs(turn) < 2 * _PHASE) & (np.abs(half - turn / 2.0) < _PHASE)
              & (np.abs(lm - (la[todo] + la[todo + 1]) / 2.0) < _LOG))
        flag = np.zeros(th.size + mid.size, bool)   # per interval's left point
        flag[:th.size - 1] = done
        flag[todo] = ok
        flag[th.size:] = ok
        order = np.argsort(np.concatenate([th, mid]), kind="stable")
        th = np.concatenate([th, mid])[order]
        ph = np.concatenate([ph, pm])[order]
        la = np.concatenate([la, lm])[order]
        done = flag[order][:-1]
    if not np.isfinite(la).all():
        return None, th.size
    w = np.angle(np.exp(1j * np.diff(ph))).sum() / np.pi   # f real at 0 and pi
    if abs(w - round(w)) > 1e-3:
        return None, th.size
    return n_out - round(w), th.size


def unstable_count(fr, tol: float = 1e-6):
    """Poles of a loop over its super-period with ``|z| > 1 + tol``, from its structure.

    Parameters
    ----------
    fr : FastResponse
        A compiled loop.
    tol : float
        Margin above ``|z| = 1`` (-).

    Returns
    -------
    int or None
        None where the loop lacks the form (:func:`period_split`) or the count is not
        certain: then only its dense eigenvalues can say.
    """
    split, _ = period_split(fr)
    if split is None:
        return None
    n = winding_count(split.A, split.U, split.W, split.n_p, tol)[0]
    if n is None or not split.watch.size:
        return n
    return n + int(np.sum(np.abs(np.linalg.eigvals(split.watch)) > 1.0 + tol))
