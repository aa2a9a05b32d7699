"""The certificate's checked models (:mod:`.certify`): the structure's sampled transfer
from its modal blocks, the controllers' per component, and the check of the modal
aliasing sum against the engine."""

from __future__ import annotations

import math

import numpy as np

from .blocks import AnalysisError
from .certify_bounds import _Modes


def _held(block, N: int):
    """``(A^N, sum_k A^k B)``: the block stepped ``N`` times with its inputs held."""
    Ar, Br = np.eye(block.A.shape[0]), np.zeros_like(block.B)
    Ab, Bb = block.A, block.B
    while N:
        if N & 1:
            Ar, Br = Ab @ Ar, Ab @ Br + Bb
        Ab, Bb = Ab @ Ab, Ab @ Bb + Bb
        N >>= 1
    return Ar, Br


class _StructureResponse:
    """The structure's sampled transfer ``C (zI - A)^-1 B + D`` (inputs held over ``N``
    steps) from its own structure: 2x2 modal blocks solved in closed form, the Ritz
    block through its eigenvectors, each acceleration filter channel by itself."""

    def __init__(self, block, N: int, rows, cols):
        m = block.model
        A, B = _held(block, N)
        n_m, ns = m.n_modes, m.n_struct_states
        n = A.shape[0]
        self.n_m, self.ns = n_m, ns
        j = np.arange(n_m)
        self.a = np.stack([A[j, j], A[j, n_m + j], A[n_m + j, j], A[n_m + j, n_m + j]])
        mask = np.zeros((n, n), bool)
        mask[j, j] = mask[j, n_m + j] = mask[n_m + j, j] = mask[n_m + j, n_m + j] = True
        mask[2 * n_m:ns, 2 * n_m:ns] = True
        mask[ns:, :] = True
        off = np.abs(np.where(mask, 0.0, A)).max(initial=0.0)
        if off > 1e-9 * np.abs(A).max():
            raise AnalysisError(f"the structure's step map is not block-diagonal in its "
                                f"modes (off-block {off:.1e}); no certificate")
        self.Bq, self.Bv = B[:n_m][:, cols], B[n_m:2 * n_m][:, cols]
        lam, V = np.linalg.eig(A[2 * n_m:ns, 2 * n_m:ns]) if ns > 2 * n_m else (
            np.zeros(0), np.zeros((0, 0)))
        if V.size and not np.linalg.cond(V) < 1e10:
            raise AnalysisError("the structure's Ritz block is not diagonalisable; "
                                "no certificate")
        self.lam = lam
        C = block.C[rows]
        self.Cq, self.Cv = C[:, :n_m], C[:, n_m:2 * n_m]
        self.Co = C[:, 2 * n_m:ns] @ V if V.size else C[:, 2 * n_m:ns]
        self.Bo = np.linalg.solve(V, B[2 * n_m:ns][:, cols]) if V.size else B[2 * n_m:ns][:, cols]
        self.Vo = V
        self.D = block.D[np.ix_(rows, cols)]
        nf = n - ns
        self.nf = nf
        if nf:
            o = m.accel_lowpass.order
            self.o = o
            self.Aff = np.stack([A[ns + c * o:ns + (c + 1) * o, ns + c * o:ns + (c + 1) * o]
                                 for c in range(nf // o)])
            blk = np.zeros((n - ns, n - ns), bool)
            for c in range(nf // o):
                blk[c * o:(c + 1) * o, c * o:(c + 1) * o] = True
            if np.abs(np.where(blk, 0.0, A[ns:, ns:])).max(initial=0.0) > 0:
                raise AnalysisError("the acceleration filters are coupled; no certificate")
            self.Afs, self.Bf, self.Cf = A[ns:, :ns], B[ns:][:, cols], C[:, ns:]
            self.Afs_o = self.Afs[:, 2 * n_m:ns] @ V if V.size else self.Afs[:, 2 * n_m:ns]

    def __call__(self, z):
        z = np.asarray(z, complex)[:, None]
        a11, a12, a21, a22 = self.a
        det = (z - a11) * (z - a22) - a12 * a21                          # (nz, n_m)
        # [[z - a22, a12], [a21, z - a11]] / det applied to (Bq, Bv)
        Xq = ((z - a22)[:, :, None] * self.Bq + a12[None, :, None] * self.Bv) / det[:, :, None]
        Xv = (a21[None, :, None] * self.Bq + (z - a11)[:, :, None] * self.Bv) / det[:, :, None]
        Xo = self.Bo[None] / (z[:, :, None] - self.lam[None, :, None])
        Y = self.Cq @ Xq + self.Cv @ Xv + self.Co @ Xo
        if self.nf:
            n_m = self.n_m
            U = (self.Afs[:, :n_m] @ Xq + self.Afs[:, n_m:2 * n_m] @ Xv
                 + self.Afs_o @ Xo + self.Bf)                               # (nz, nf, m)
            o, nc = self.o, self.nf // self.o
            Ac = z[:, None, :, None] * np.eye(o) - self.Aff[None]          # (nz, nc, o, o)
            Uc = U.reshape(U.shape[0], nc, o, -1)
            Xf = np.linalg.solve(Ac, Uc).reshape(U.shape)
            Y = Y + self.Cf @ Xf
        return Y + self.D


class _Components:
    """``R (zI - Phi)^-1 Gam + Dl`` solved per connected component of ``Phi``."""

    def __init__(self, Phi, Gam, R, Dl):
        from scipy.sparse.csgraph import connected_components

        _, lab = connected_components(np.abs(Phi) + np.abs(Phi.T) > 0, directed=False)
        self.parts = []
        for c in np.unique(lab):
            idx = np.flatnonzero(lab == c)
            if np.abs(Gam[idx]).max(initial=0) > 0 and np.abs(R[:, idx]).max(initial=0) > 0:
                self.parts.append((Phi[np.ix_(idx, idx)], Gam[idx], R[:, idx]))
        self.Dl = Dl

    def __call__(self, z, rows, cols):
        z = np.asarray(z, complex)
        out = np.broadcast_to(self.Dl[np.ix_(rows, cols)],
                              (z.size, len(rows), len(cols))).astype(complex)
        for Ph, G, R in self.parts:
            k = Ph.shape[0]
            A = z[:, None, None] * np.eye(k) - Ph
            X = np.linalg.solve(A, np.broadcast_to(G[:, cols], (z.size, k, len(cols))))
            out = out + R[rows] @ X
        return out

    def relevant(self, rows, cols):
        """Drop the components that do not reach ``rows`` from ``cols``."""
        self.parts = [(Ph, G, R) for Ph, G, R in self.parts
                      if np.abs(G[:, cols]).max(initial=0) > 0
                      and np.abs(R[rows]).max(initial=0) > 0]
        return self


def _structure_response(block, N: int, z, rows, cols):
    """The structure block's transfer with its inputs held over ``N`` of its steps and
    its outputs sampled every ``N`` steps (dense solves, for checks)."""
    Ar, Br = _held(block, N)
    C, D = block.C[rows], block.D[np.ix_(rows, cols)]
    n = Ar.shape[0]
    return np.array([C @ np.linalg.solve(zz * np.eye(n) - Ar, Br[:, cols]) + D for zz in z])


def _model_check(lin_c, uset, bl, yi, ui, y_ch, md: _Modes, in_cols, gmap, N, sresp,
                 Kresp) -> float:
    """Largest relative difference of four comparisons at a few frequencies: the loop's
    structure block against the structure's own sampled transfer, the fast structure
    and controller responses against dense solves, and the structure's deviation at a
    point of the set against the modal aliasing sum."""
    from .modalset import _factors, loop_at

    rng = np.random.default_rng(7)
    vals = {}
    for it in uset.items:
        lo, hi = uset.bounds(it.name)
        n = len(uset.modes[it.name])
        vals[it.name] = (lo + (hi - lo) * rng.uniform(0.2, 0.8, n) if it.per_mode
                         else np.array([lo + 0.3 * (hi - lo)]))
    S = uset.structure
    sb = lin_c.blocks[S]
    rows = [sb.outputs.index(c.split(".", 1)[1]) for c in y_ch]
    th = np.array([0.05, 0.4, 1.1, 2.3, 3.0])
    z = np.exp(1j * th)
    G0 = _structure_response(sb, N, z, rows, in_cols)
    n_bl = bl.Phi.shape[0]
    Ld = np.array([bl.R @ np.linalg.solve(zz * np.eye(n_bl) - bl.Phi, bl.Gam) + bl.Dl
                   for zz in z])
    loop, K = Ld[:, yi][:, :, ui], Ld[:, ui][:, :, yi]

    def rel(a, b, ref=None):    # row by row: channels of very different scales
        ref = np.abs(b if ref is None else ref).max(axis=-1, keepdims=True)
        return float((np.abs(a - b) / (ref + 1e-300)).max())

    err_a = max(rel(G0 @ gmap, loop), rel(sresp(z) @ gmap, loop), rel(Kresp(z, ui, yi), K))
    Gp = _structure_response(loop_at(lin_c, uset, vals).blocks[S], N, z, rows, in_cols)
    dev = Gp - G0
    fwp, fzp, _ = _factors(uset, vals, sb.model.n_modes)
    fwp, fzp = fwp[md.U], fzp[md.U]
    b_in = sb.model.B_e[np.ix_(md.U, in_cols)]
    A2 = int(min(20000, max(2000, math.ceil(200 * md.w0.max() / md.Om))))
    m = np.arange(-A2, A2 + 1)
    err_b = 0.0
    for t, dv in zip(th, dev):
        s = 1j * (t / md.P + m * md.Om)
        H0 = np.where(s == 0, md.P, (1 - np.exp(-s * md.P)) / np.where(s == 0, 1, s))
        kap = md.kappa(s)
        w, c = md.w0[:, None], md.c0[:, None]
        dh = (1 / ((w * fwp[:, None]) ** 2 + s * c * (fwp * fzp)[:, None] + s * s)
              - 1 / (w * w + s * c + s * s))                           # (n, a)
        cj = np.zeros((md.C.shape[0], md.w0.size), complex)
        for q in (0, 1, 2):
            r = md.kinds == q
            if r.any():
                cj[r] = md.C[r] * (dh @ (kap[q] * H0))[None, :] / md.P
        err_b = max(err_b, rel(cj @ b_in, dv, np.maximum(
            np.abs(dv).max(axis=-1, keepdims=True),
            1e-4 * np.abs(G0).max(axis=(0, 2))[:, None])))
    return max(err_a, err_b)
