"""A robust-stability certificate over a modal uncertainty set, for the sampled-data loop.

:func:`certify` gives ``margin_guaranteed``: the largest scale ``k`` of the set about
nominal (each factor's range ``[1 - k (1 - low), 1 + k (high - 1)]``) for which every
point is proven stable.  The proof is zero exclusion on a frequency grid:

* **Loop form.**  The loop is broken twice, at the structure's outputs read by the loop
  and at the loop's commands into the structure (:func:`~orchestrator.analysis.loops.
  broken_loop`), over one loop period ``P``: ``P0(z)`` (structure) and ``K(z)``
  (controllers, amplifiers, the ACS, with their delays and holds).  Closing both gives
  back the scenario's poles (checked).
* **Modes enter additively.**  The structure's modes are decoupled: mode ``j`` moves
  ``P0`` by ``dP_j(z) = c_j(z) b_j^T``, with ``b_j`` its modal input row and ``c_j`` its
  sampled output.  The input is held over ``P``, so ``c_j`` is the exact aliasing sum of
  the continuous mode (zero-order hold, every alias)::

      c_j(e^{i nu P}) = (1/P) sum_m w_j(i nu_m) H0(i nu_m) dh_j(i nu_m),
      nu_m = nu + 2 pi m / P,  H0(s) = (1 - e^{-sP}) / s,
      dh_j(s) = 1/(s^2 + c s + w^2) - 1/(s^2 + c0 s + w0^2),

  ``w_j(s)`` the mode's shape on the outputs times ``1``, ``s`` or ``s^2 F(s)`` for
  displacement, rate and (filtered) acceleration outputs.  Modes above the loop's
  Nyquist frequency alias as they do.  The model is checked against the engine's exact
  sampled structure at a point of the set before anything is certified.
* **Value sets.**  For ``(w, c)`` in the scaled box, ``d = w^2 - nu^2 + i nu c`` lies in
  a rectangle; ``|dh| = |d - d0| / (|d| |d0|)`` is bounded by its exact maximum over the
  rectangle's edges (``log|d - d0| - log|d|`` is subharmonic there, so the maximum is on
  the boundary).  Aliases beyond ``2 w_max`` are bounded in closed form.
* **Zero exclusion.**  With ``M(z) = b^T (I - K P0)^-1 K``, the perturbed loop is
  singular at ``z`` only if ``I - E`` is, ``E_ij = M_i c_j``; ``|E_ij| <= N_ij`` (the
  resonant aliases with their direction, the others entrywise).  Each mode's own loop
  is taken exactly at its nearest alias: ``1 - E_jj = beta (d - d*) / d - (rest)``, so
  ``|1 - E_jj| >= L_j = |beta| min |d - d*| / |d| - rest`` over the rectangle (a lightly
  damped mode moved by many bandwidths keeps its phase: no disk around it).  With every
  ``L_j > 0`` and ``rho(N_off / L) < 1`` (Collatz-Wielandt bound), ``I - E`` is
  nonsingular.  The nominal loop stable, the
  modes' deviations stable and the scaled sets nested, no pole crosses the unit circle
  for any point up to that ``k``.

What it covers, exactly: the modal frequency and damping factors (not gains), the loops
of one rate (the instances on a path from the structure's outputs back to its inputs,
all at one period ``P``, the structure stepping at a divisor of it).  With loops at
several rates (a 10 Hz ACS beside 1 kHz isolation laws) the fastest rate's loops are
certified with the slower instances opened, and ``covers`` says which were opened.
Frequency is gridded (every mode's band and nominal resonance, every lightly damped
closed-loop pole refined; ``frequencies`` gives the count): between grid points the bound
is not proven, as in any gridded structured-singular-value analysis.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .blocks import AnalysisError

__all__ = ["certify", "loop_members", "dh_bound"]

_CHUNK = 256


def _port_dependence(block) -> np.ndarray:
    """Which outputs of a block depend on which inputs (bool, ``(n_out, n_in)``)."""
    n_out, n_in = len(block.outputs), len(block.inputs)
    if block.kind == "source" or not block.active or n_in == 0:
        return np.zeros((n_out, n_in), bool)
    A, B = np.abs(block.A) > 0, np.abs(block.B) > 0
    reach = B.copy()
    while True:
        new = reach | ((A.astype(np.int64) @ reach.astype(np.int64)) > 0)
        if (new == reach).all():
            break
        reach = new
    C = (np.abs(block.C) > 0).astype(np.int64)
    return (np.abs(block.D) > 0) | ((C @ reach.astype(np.int64)) > 0)


def loop_members(lin, structure: str) -> list:
    """Instances on a path from the structure's outputs back to its inputs.

    Parameters
    ----------
    lin : LinearScenario
    structure : str
        The structure instance.

    Returns
    -------
    list of str
        In the scenario's order.
    """
    deps = {n: _port_dependence(b) for n, b in lin.blocks.items() if n != structure}
    conns = [c for c in lin._conns if c[4] != 0]
    fwd = {(structure, i) for i in range(len(lin.blocks[structure].outputs))}
    changed = True
    while changed:
        changed = False
        for t, j, s, i, _ in conns:
            if (s, i) in fwd and t != structure:
                for o in np.flatnonzero(deps[t][:, j]):
                    if (t, int(o)) not in fwd:
                        fwd.add((t, int(o)))
                        changed = True
    bwd = {(s, i) for t, j, s, i, _ in conns if t == structure}
    changed = True
    while changed:
        changed = False
        for t, j, s, i, _ in conns:
            if t == structure or not any((t, int(o)) in bwd
                                         for o in np.flatnonzero(deps[t][:, j])):
                continue
            if (s, i) not in bwd:
                bwd.add((s, i))
                changed = True
    both = {p[0] for p in fwd & bwd if p[0] != structure}
    return [n for n in lin.order if n in both]


def _seg_max(p, q, d0, pick=np.maximum):
    """Max (or, with ``pick=np.minimum``, min) of ``|d - d0|^2 / |d|^2`` over the segment
    ``d = p + t q``, ``t in [0, 1]``."""
    a = np.abs(q) ** 2
    u = p - d0
    b1, c1 = 2 * (q.conj() * u).real, np.abs(u) ** 2
    b2, c2 = 2 * (q.conj() * p).real, np.abs(p) ** 2

    def f(t):
        return (a * t * t + b1 * t + c1) / (a * t * t + b2 * t + c2)

    best = pick(f(0.0), f(1.0))
    al, be, ga = a * (b2 - b1), 2 * a * (c2 - c1), b1 * c2 - c1 * b2
    disc = be * be - 4 * al * ga
    ok = (disc >= 0) & (np.abs(al) > 0)
    sq = np.sqrt(np.where(ok, disc, 0.0))
    den = np.where(ok, 2 * al, 1.0)
    for r in ((-be + sq) / den, (-be - sq) / den):
        inside = ok & (r > 0) & (r < 1)
        best = np.where(inside, pick(best, f(np.where(inside, r, 0.0))), best)
    lin_ = (np.abs(al) == 0) & (np.abs(be) > 0)
    r = -ga / np.where(lin_, be, 1.0)
    inside = lin_ & (r > 0) & (r < 1)
    return np.where(inside, pick(best, f(np.where(inside, r, 0.0))), best)


def _rect(nu, w0, c0, fw, fz):
    """Corners of the rectangle holding ``d = w^2 - nu^2 + i |nu| c`` over the box."""
    nu = np.abs(nu)
    re_lo = (w0 * fw[0]) ** 2 - nu * nu
    re_hi = (w0 * fw[1]) ** 2 - nu * nu
    im_lo = nu * c0 * fw[0] * fz[0]
    im_hi = nu * c0 * fw[1] * fz[1]
    return (re_lo + 1j * im_lo, re_hi + 1j * im_lo, re_hi + 1j * im_hi, re_lo + 1j * im_hi)


def _ratio_min(corners, dstar):
    """Min of ``|d - d*| / |d|`` over the rectangle (0 when ``d*`` is inside it):
    ``log|d - d*| - log|d|`` is harmonic off ``d*``, so the minimum is on the edges."""
    a, b, c, d = corners
    m = np.minimum.reduce([_seg_max(a, b - a, dstar, np.minimum),
                           _seg_max(b, c - b, dstar, np.minimum),
                           _seg_max(c, d - c, dstar, np.minimum),
                           _seg_max(d, a - d, dstar, np.minimum)])
    inside = ((dstar.real >= a.real) & (dstar.real <= b.real)
              & (dstar.imag >= a.imag) & (dstar.imag <= c.imag))
    return np.where(inside, 0.0, np.sqrt(m) * (1 - 1e-12))


def dh_bound(nu, w0, c0, fw, fz):
    """Bound on ``|dh(i nu)|`` of one mode over a box of frequency and damping factors.

    Parameters
    ----------
    nu : array_like
        Angular frequencies (rad/s); broadcast with the mode's arrays.
    w0, c0 : array_like
        Nominal natural frequency (rad/s) and damping coefficient ``2 zeta w`` (1/s).
    fw, fz : tuple of array_like
        ``(low, high)`` factors on the frequency and on the damping ratio (> 0); the
        damping coefficient moves by ``fw fz``.

    Returns
    -------
    ndarray
        ``max |1/d - 1/d0|`` over the box (exact maximum over the rectangle holding
        ``d``), with ``d = w^2 - nu^2 + i nu c``.
    """
    nu = np.abs(np.asarray(nu, float))
    d0 = (w0 * w0 - nu * nu) + 1j * nu * c0
    a, b, c, d = _rect(nu, w0, c0, fw, fz)
    m = np.maximum.reduce([_seg_max(a, b - a, d0), _seg_max(b, c - b, d0),
                           _seg_max(c, d - c, d0), _seg_max(d, a - d, d0)])
    return np.sqrt(m) / np.abs(d0) * (1 + 1e-12)


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


def _dh_loose(nu, w0, c0, fw, fz):
    """Cheaper bound on ``|dh(i nu)|``: farthest corner over nearest point (valid
    everywhere, tight away from the mode's band)."""
    nu = np.abs(nu)
    re_lo = (w0 * fw[0]) ** 2 - nu * nu
    re_hi = (w0 * fw[1]) ** 2 - nu * nu
    im_lo = nu * c0 * fw[0] * fz[0]
    im_hi = nu * c0 * fw[1] * fz[1]
    d0r, d0i = w0 * w0 - nu * nu, nu * c0
    far = np.sqrt(np.maximum(np.abs(re_lo - d0r), np.abs(re_hi - d0r)) ** 2
                  + np.maximum(np.abs(im_lo - d0i), np.abs(im_hi - d0i)) ** 2)
    gap_re = np.where(re_lo > 0, re_lo, np.where(re_hi < 0, -re_hi, 0.0))
    near = np.sqrt(gap_re ** 2 + im_lo ** 2)
    return far / (near * np.hypot(d0r, d0i)) * (1 + 1e-12)


class _Modes:
    """The uncertain modes seen by the loop: shapes, inputs, kinds and boxes."""

    def __init__(self, model, U, items, uset, C, kinds, beta, P, lowpass):
        self.U = U
        self.w0 = model.omega[U]
        self.c0 = model.modal_damping[U]
        self.P, self.Om = P, 2 * math.pi / P
        self.C, self.kinds, self.beta = C, kinds, beta          # (p, n), (p,), (n, m)
        self.ranges = []                                        # per item: modes, lo, hi
        pos = {int(u): k for k, u in enumerate(U)}
        for it in items:
            lo, hi = uset.bounds(it.name)
            self.ranges.append((it.kind, np.array([pos[int(j)] for j in uset.modes[it.name]]),
                                lo, hi))
        self.k_lim = min([1.0 / (1.0 - lo) for _, _, lo, _ in self.ranges if lo < 1]
                         + [math.inf])
        self.lowpass = lowpass

    def box(self, k: float):
        """Per-mode ``(fw_lo, fw_hi), (fz_lo, fz_hi)`` at scale ``k``."""
        n = self.w0.size
        fw, fz = [np.ones(n), np.ones(n)], [np.ones(n), np.ones(n)]
        for kind, idx, lo, hi in self.ranges:
            t = fw if kind == "modal_frequency" else fz
            t[0][idx] *= 1 - k * (1 - lo)
            t[1][idx] *= 1 + k * (hi - 1)
        return tuple(fw), tuple(fz)

    def kappa(self, s):
        """Output factors of the three kinds at ``s`` (displacement, rate, accel)."""
        acc = s * s
        if self.lowpass is not None:
            a, b, c = self.lowpass
            I = np.eye(a.shape[0])
            x = np.linalg.solve(s[..., None, None] * I - a, np.broadcast_to(
                b, s.shape + b.shape))
            acc = acc * (c @ x)[..., 0, 0]
        return np.ones_like(s), s, acc

    def tail(self, k: float, A) -> np.ndarray:
        """Closed-form bound of the aliases ``|m| > A`` per output kind and mode
        (``|nu_m| >= (A - 1/2) Om >= 2 w_hi``; shape (3, n), per unit mode shape)."""
        fw, fz = self.box(k)
        w, c = self.w0, self.c0
        dr = w * w * np.maximum(fw[1] ** 2 - 1, 1 - fw[0] ** 2)
        di = c * np.maximum(fw[1] * fz[1] - 1, 1 - fw[0] * fz[0])
        x = np.asarray(A, float) - 0.5

        def s(q):    # sum over |m| > A of |nu_m|^-q
            return 2 * x ** (1 - q) / ((q - 1) * self.Om ** q)

        # |w| <= nu^q' |shape| (q' = 0, 1, 2; |F| <= 1), |H0| <= 2/nu,
        # |dh| <= (16/9) (dr + nu di) / nu^4
        out = np.stack([dr * s(5) + di * s(4), dr * s(4) + di * s(3), dr * s(3) + di * s(2)])
        return out * 2 * 16 / (9 * self.P)


class _Bound:
    """``N(z; k)`` of a set of grid frequencies, its k-independent parts kept.

    Mode ``j``'s aliases up to ``|nu_m| <= 2 w_hi`` are summed (those in its band with
    their direction through ``M``, the others entrywise, ``sum_y |M_iy| |w_jy|``), the rest in
    closed form (:meth:`_Modes.tail`).
    """

    def __init__(self, modes: _Modes, nu, M, k_hi: float):
        self.modes, self.nu = modes, nu
        md = modes
        nz, n = nu.size, md.w0.size
        fw, _ = md.box(k_hi)
        self.Aj = np.maximum(3, np.ceil(2 * md.w0 * fw[1] / md.Om + 1)).astype(int)
        A = int(self.Aj.max())
        m = np.arange(-A, A + 1)
        num = nu[:, None] + m[None, :] * md.Om                          # (z, a)
        kap = md.kappa(1j * num)                                        # 3 x (z, a)
        H0 = _hold(num, md.P)
        self.absM = np.abs(M)                                            # (z, n, p)
        self.absC = np.abs(md.C)                                         # (p, n)
        an = np.abs(num)[:, None, :]
        lo, hi = 0.97 * md.w0 * fw[0], 1.03 * md.w0 * fw[1]
        res = (an >= lo[None, :, None]) & (an <= hi[None, :, None])
        # every mode's nearest alias is taken with its phase (its own loop exactly)
        nearest = np.argmin(np.abs(an - md.w0[None, :, None]), axis=2)
        np.put_along_axis(res, nearest[:, :, None], True, axis=2)
        near = np.abs(m)[None, None, :] <= self.Aj[None, :, None]
        # non-resonant aliases within |m| <= A_j: flat lists
        zi, ji, ai = np.nonzero(near & ~res)
        wq = np.stack([np.abs(kap[q][zi, ai]) * H0[zi, ai] / md.P for q in (0, 1, 2)])
        self.nr = (zi, ji, num[zi, ai], wq)
        # resonant aliases: with their direction
        R = max(int(res.sum(axis=2).max()), 1)
        # resonant first, the nearest to the nominal mode first of all
        key = np.where(res, np.abs(an - md.w0[None, :, None]), np.inf)
        order = np.argsort(key, axis=2, kind="stable")[:, :, :R]
        valid = np.take_along_axis(res, order, axis=2)                 # (z, n, R)
        MC = [M[:, :, md.kinds == q] @ md.C[md.kinds == q] for q in (0, 1, 2)]
        G = np.zeros((nz, n, n, R), np.float32)
        for r in range(R):
            acc = 0
            for q in (0, 1, 2):
                kq = np.take_along_axis(kap[q], order[:, :, r], axis=1)    # (z, n)
                acc = acc + MC[q] * kq[:, None, :]
            G[..., r] = np.abs(acc) * (1 + 1e-6)      # rounded up in single precision
        self.G = G * valid[:, None, :, :]
        nsel = np.take_along_axis(np.broadcast_to(num[:, None, :], res.shape), order, axis=2)
        self.rs = (nsel, _hold(nsel, md.P) / md.P * valid)
        # the nearest resonant alias of each mode on its own loop, with its phase:
        # M_jj c_j = alpha dh(i nu0) + (the other aliases, bounded)
        nu0 = nsel[:, :, 0]
        s0 = 1j * nu0
        H0c = np.where(nu0 == 0, md.P, (1 - np.exp(-s0 * md.P)) / np.where(nu0 == 0, 1, s0))
        jj = np.arange(n)
        self.alpha = sum(MC[q][:, jj, jj] * np.take_along_axis(kap[q], order[:, :, 0], axis=1)
                         for q in (0, 1, 2)) * H0c / md.P * valid[:, :, 0]
        self.nu0, self.has0 = nu0, valid[:, :, 0]

    def take(self, keep):
        """Keep the grid points ``keep`` (bool)."""
        idx = np.flatnonzero(keep)
        new = np.full(self.nu.size, -1)
        new[idx] = np.arange(idx.size)
        zi, ji, num, w = self.nr
        sel = np.isin(zi, idx)
        self.nr = (new[zi[sel]], ji[sel], num[sel])
        self.nr = self.nr[:3] + (w[:, sel],)
        self.nu, self.absM, self.G = self.nu[idx], self.absM[idx], self.G[idx]
        self.rs = (self.rs[0][idx], self.rs[1][idx])
        self.alpha, self.nu0, self.has0 = self.alpha[idx], self.nu0[idx], self.has0[idx]
        return self

    def rho(self, k: float) -> np.ndarray:
        """Collatz-Wielandt upper bound of ``rho(N(z; k))`` at every kept point."""
        md = self.modes
        fw, fz = md.box(k)
        nz, n = self.nu.size, md.w0.size
        zi, ji, num, w = self.nr
        r = _dh_loose(num, md.w0[ji], md.c0[ji], (fw[0][ji], fw[1][ji]),
                      (fz[0][ji], fz[1][ji]))
        Sq = np.stack([np.bincount(zi * n + ji, w[q] * r, minlength=nz * n).reshape(nz, n)
                       for q in (0, 1, 2)]) + md.tail(k, self.Aj)[:, None, :]   # (3, z, n)
        W = self.absC[None] * np.moveaxis(Sq[md.kinds], 0, 1)                 # (z, p, n)
        par = [x[None, :, None] for x in (md.w0, md.c0, fw[0], fw[1], fz[0], fz[1])]
        w0, c0, f0, f1, z0, z1 = par
        Ts = dh_bound(self.rs[0], w0, c0, (f0, f1), (z0, z1)) * self.rs[1]
        N = np.einsum("zijr,zjr->zij", self.G, Ts) + self.absM @ W
        # each mode's own loop exactly at its nearest alias: |1 - M_jj c_j| >= L_j
        jj = np.arange(n)
        diag = N[:, jj, jj]
        rest = diag - self.G[:, jj, jj, 0] * Ts[:, :, 0]
        w0, c0 = md.w0[None, :], md.c0[None, :]
        nu0 = self.nu0
        d0 = w0 * w0 - nu0 * nu0 + 1j * nu0 * c0
        beta = 1 + self.alpha / d0
        dstar = self.alpha / np.where(beta == 0, 1, beta)
        dstar = np.where(nu0 < 0, dstar.conj(), dstar)     # rectangle of |nu|
        corners = _rect(nu0, w0, c0, (fw[0][None], fw[1][None]), (fz[0][None], fz[1][None]))
        exact = np.abs(beta) * _ratio_min(corners, dstar) - rest
        L = np.where(self.has0, exact, 1.0 - diag)
        N[:, jj, jj] = 0.0
        rho = _collatz(N / np.where(L > 0, L, 1.0)[:, :, None])
        return np.where((L > 0).all(axis=1), rho, np.inf)


def _hold(num, P):
    """``|H0(i nu)| = |2 sin(nu P / 2) / nu|`` (``P`` at 0)."""
    safe = np.where(num == 0, 1.0, np.abs(num))
    return np.where(num == 0, P, np.abs(2 * np.sin(num * P / 2)) / safe)


def _collatz(N, iters: int = 40) -> np.ndarray:
    """Upper bound ``max_i (N x)_i / x_i`` of the Perron root for a positive ``x`` from
    power iteration (any positive ``x`` gives a bound)."""
    n = N.shape[1]
    x = np.ones(N.shape[:2])
    floor = 1e-30 + 1e-12 * N.max(axis=(1, 2))[:, None]
    for _ in range(iters):
        y = np.einsum("zij,zj->zi", N, x) + floor
        x = y / y.max(axis=1, keepdims=True)
    y = np.einsum("zij,zj->zi", N, x)
    return (y / x).max(axis=1) if n else np.zeros(N.shape[0])


def _moving_radius(ev) -> float:
    moving = np.abs(ev - 1.0) > 1e-6
    return float(np.abs(ev[moving]).max()) if moving.any() else 0.0


def _grid(md: _Modes, k_hi: float, poles, n_log: int = 400) -> np.ndarray:
    """Grid of ``nu`` (rad/s) on ``(0, pi/P]``: log-spaced, each mode's band and nominal
    resonance folded by aliasing, and every lightly damped closed-loop pole refined."""
    P, Om = md.P, md.Om
    nyq = math.pi / P
    pts = [np.geomspace(1e-5 * nyq, nyq, n_log)]
    fw, _ = md.box(k_hi)
    grade = np.sinh(np.linspace(-math.asinh(40), math.asinh(40), 49))
    for w, c, lo, hi in zip(md.w0, md.c0, md.w0 * fw[0], md.w0 * fw[1]):
        band = np.linspace(0.95 * lo, 1.05 * hi, 24)
        pts += [band, w + 0.5 * c * grade]
    for lam in poles:
        r = abs(lam)
        if 0.8 < r < 1 and abs(lam - 1) > 1e-6:
            sig = -math.log(r)
            pts.append((abs(np.angle(lam)) + sig * grade) / P)
    nu = np.abs(np.concatenate(pts))
    nu = np.mod(nu, Om)
    nu = np.where(nu > nyq, Om - nu, nu)
    return np.unique(np.clip(nu, 1e-5 * nyq, nyq))


def _band_grid(md: _Modes, k: float, cap: int = 4000) -> np.ndarray:
    """Each mode's band at scale ``k``, spaced at a third of the half-power width of its
    least damped point, folded into ``(0, pi/P]``."""
    fw, fz = md.box(k)
    pts = []
    for w, lo, hi, c in zip(md.w0, md.w0 * fw[0], md.w0 * fw[1], md.c0 * fw[0] * fz[0]):
        step = max(c / 6, 1e-9 * w)
        pts.append(np.linspace(0.98 * lo, 1.02 * hi, int(min(cap, (1.04 * hi - 0.96 * lo) / step
                                                              + 2))))
    nu = np.mod(np.concatenate(pts), md.Om)
    nyq = math.pi / md.P
    nu = np.where(nu > nyq, md.Om - nu, nu)
    return np.unique(np.clip(nu, 1e-5 * nyq, nyq))


def _refuse(text: str, **extra) -> dict:
    return {"margin_guaranteed": None, "certificate": text, **extra}


def certify(lin, uset, *, k_max: float = 4.0, tol: float = 0.005, progress=None,
            check: bool = True) -> dict:
    """The largest scale of the set proven stable (see the module docstring).

    Parameters
    ----------
    lin : LinearScenario
        The nominal loop.
    uset : UncertainSet
        From :func:`~orchestrator.analysis.robust.uncertain_set`.
    k_max : float
        Largest scale tried (-); it is also cut where a factor's lower bound reaches 0.
    tol : float
        Resolution of ``k`` (-).
    progress : callable, optional
        ``progress(text)`` for each stage.
    check : bool
        Check the modal model against the engine's sampled structure at a point of the
        set first (refuse on a mismatch).

    Returns
    -------
    dict
        ``margin_guaranteed`` (None when nothing is certified, with the reason in
        ``certificate``), ``certificate`` (what it covers), ``covers``, ``opened``,
        ``period_s``, ``frequencies``, ``worst_hz``, ``model_check``, ``wall_s``.
    """
    from .loops import broken_loop

    t0 = time.perf_counter()
    say = progress or (lambda text: None)
    if any(it.kind == "gain" for it in uset.items):
        return _refuse("not computed: the set has gain parameters; the certificate covers "
                       "modal frequency and damping factors only")
    S = uset.structure
    model = lin.blocks[S].model
    U = np.array(sorted(set().union(*[set(map(int, v)) for v in uset.modes.values()])))
    members = loop_members(lin, S)
    opened = []
    if members:
        fast = min(lin.blocks[m].period for m in members)
        opened = [m for m in members if lin.blocks[m].period > fast]
        if opened:
            lin = lin.opened(opened, period=fast)
            members = loop_members(lin, S)
    others = [n for n in lin.blocks if n != S and n not in members]
    P_t = lin.blocks[members[0]].period if members else lin.blocks[S].period
    if P_t % lin.blocks[S].period:
        return _refuse(f"not computed: the loop's period ({P_t} ticks) is not a multiple "
                       f"of the structure's ({lin.blocks[S].period})")
    lin_c = lin.opened(others, period=P_t) if others else lin
    P = P_t * lin.base
    kin = np.where(model.is_accel, 2, np.where(model.is_rate, 1, 0))
    lowpass = model.accel_lowpass.siso() if model.accel_lowpass is not None else None
    what = (f"modal frequency and damping factors of {U.size} modes of {S!r}; loops "
            f"{', '.join(members) or 'none'} at {P:g} s")
    if opened:
        what += f"; with {', '.join(opened)} opened (slower loops not covered)"
    if not members:
        md = _Modes(model, U, uset.items, uset, np.zeros((0, U.size)), np.zeros(0, int),
                    np.zeros((U.size, 0)), P, lowpass)
        k = min(k_max, md.k_lim * (1 - 1e-9))
        return _result(k, what, opened, P, 0, None, None, t0,
                       "no loop closes through the structure at this rate: every point with "
                       "positive damping is stable")
    if lin_c.hyper != P_t:
        return _refuse(f"not computed: the loop's instances run every {P_t} ticks but its "
                       f"hyperperiod is {lin_c.hyper}")
    y_ch, u_ch = [], []
    for t, j, s, i, g in lin_c._conns:
        if s == S and t in members:
            c = f"{S}.{lin_c.blocks[S].outputs[i]}"
            y_ch += [c] if c not in y_ch else []
        if t == S and s in members:
            c = f"{s}.{lin_c.blocks[s].outputs[i]}"
            u_ch += [c] if c not in u_ch else []
    say(f"certificate: loop broken at {len(y_ch)} outputs and {len(u_ch)} commands, "
        f"period {P:g} s")
    bl = broken_loop(lin_c, y_ch + u_ch, faster=True)
    chans = list(bl.channels)
    yi, ui = [chans.index(c) for c in y_ch], [chans.index(c) for c in u_ch]
    ev_cl = np.linalg.eigvals(bl.closed(np.ones(len(chans))))
    r_lin = _moving_radius(ev_cl)
    if r_lin >= 1.0:
        return _result(0.0, what, opened, P, 0, None, None, t0,
                       f"the nominal loop is unstable (|z| = {r_lin:.6f})")
    yo = [model.output_names.index(c.split(".", 1)[1]) for c in y_ch]
    feeds = [(j, u_ch.index(f"{s}.{lin_c.blocks[s].outputs[i]}"), g)
             for t, j, s, i, g in lin_c._conns if t == S and s in members]
    in_cols = sorted({j for j, _, _ in feeds})
    gmap = np.zeros((len(in_cols), len(u_ch)))
    for j, c, g in feeds:
        gmap[in_cols.index(j), c] += g
    beta = model.B_e[np.ix_(U, in_cols)] @ gmap
    md = _Modes(model, U, uset.items, uset, model.C_e[np.ix_(yo, U)], kin[yo], beta, P,
                lowpass)
    k_hi = min(k_max, md.k_lim * 0.999)
    N_s = P_t // lin_c.blocks[S].period
    Kresp = _Components(bl.Phi, bl.Gam, bl.R, bl.Dl).relevant(ui, yi)
    sresp = _StructureResponse(lin_c.blocks[S], N_s, yo, in_cols)
    z2 = np.exp(1j * np.array([0.3, 1.7]))
    n_bl = bl.Phi.shape[0]
    Ld = np.array([bl.R @ np.linalg.solve(zz * np.eye(n_bl) - bl.Phi, bl.Gam) + bl.Dl
                   for zz in z2])
    if (np.abs(Ld[:, yi][:, :, yi]).max() > 0 or np.abs(Ld[:, ui][:, :, ui]).max() > 0):
        return _refuse("not computed: a path of the loop bypasses the structure's outputs "
                       "or commands (the loop is not structure-controller)")
    mcheck = (_model_check(lin_c, uset, bl, yi, ui, y_ch, md, in_cols, gmap, N_s, sresp,
                           Kresp) if check else None)
    if mcheck is not None and not mcheck < 1e-6:
        return _refuse(f"not computed: the modal model differs from the engine's sampled "
                       f"loop by {mcheck:.2e} (the loop does not hold the structure's inputs "
                       "over its period)", model_check=mcheck)
    def scan(nu, k_test, k_box):
        """The grid points of ``nu`` not proven at ``k_test`` (their bounds kept)."""
        kept = []
        for c0 in range(0, nu.size, _CHUNK):
            z = np.exp(1j * nu[c0:c0 + _CHUNK] * P)
            K, P0 = Kresp(z, ui, yi), sresp(z) @ gmap
            M = np.einsum("nu,zuy->zny", beta,
                          np.linalg.solve(np.eye(len(u_ch)) - K @ P0, K))
            b = _Bound(md, nu[c0:c0 + _CHUNK], M, k_box)
            fail = b.rho(k_test) >= 1.0
            if fail.any():
                kept.append(b.take(fail))
        return kept

    def bisect(kept, lo, hi):
        while hi - lo > tol * max(hi, 1e-3):
            mid = 0.5 * (lo + hi)
            bad = any((b.rho(mid) >= 1.0).any() for b in kept)
            lo, hi = (lo, mid) if bad else (mid, hi)
        return lo, hi

    nu = _grid(md, k_hi, ev_cl)
    say(f"certificate: {nu.size} frequencies, {U.size} modes, k up to {k_hi:.3g}")
    kept = scan(nu, k_hi, k_hi)
    k_g, hi = (k_hi, k_hi) if not kept else bisect(kept, 0.0, k_hi)
    n_freq = nu.size
    # refine: every mode's band at the spacing of the narrowest resonance in the box
    # at the scale reached, until that scale holds on the refined grid
    for _ in range(6):
        if k_g <= 0:
            break
        fine = _band_grid(md, min(k_hi, k_g * (1 + 2 * tol)))
        n_freq += fine.size
        say(f"certificate: k {k_g:.4g} on {n_freq - fine.size} frequencies; checking "
            f"{fine.size} more in the modes' bands")
        more = scan(fine, k_g, min(k_hi, k_g * (1 + 2 * tol)))
        if not more:
            break
        kept += more
        k_g, hi = bisect(kept, 0.0, k_g)
    worst = None
    for b in kept:
        r = b.rho(hi)
        if (r >= 1.0).any():
            worst = float(b.nu[int(np.argmax(r))] / (2 * math.pi))
            break
    nu = np.zeros(n_freq)
    return _result(k_g, what, opened, P, nu.size, worst, mcheck, t0,
                   f"proven stable for every point of the set scaled by {k_g:.3g} about "
                   f"nominal ({what}), on {nu.size} frequencies")


def _result(k, what, opened, P, n_freq, worst, mcheck, t0, text) -> dict:
    """The answer; with slower loops opened, the scale holds for the fast loops only and
    ``margin_guaranteed`` is None (``margin_partial`` keeps it)."""
    out = {"margin_guaranteed": float(k), "margin_partial": float(k), "complete": True,
           "covers": what, "opened": opened, "certificate": text, "period_s": P,
           "frequencies": int(n_freq), "worst_hz": worst, "model_check": mcheck,
           "wall_s": time.perf_counter() - t0}
    if opened:
        out.update(margin_guaranteed=None, complete=False,
                   certificate=f"not for the whole loop (loops at several rates): {text}; "
                               f"{', '.join(opened)} opened, not covered")
    return out


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
    from .robust import _factors, loop_at

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
            1e-6 * np.abs(G0).max(axis=(0, 2))[:, None])))
    return max(err_a, err_b)
