"""Value sets, bounds and frequency grids of the certificate (:mod:`.certify`).

A mode's deviation ``dh = 1/d - 1/d0`` over a box of frequency and damping factors:
``d = w^2 - nu^2 + i nu c`` lies in a rectangle, and the extremes of
``|d - d0| / |d|`` over it are on its edges (exact per edge: a ratio of quadratics).
:class:`_Bound` assembles ``N(z; k)`` per grid frequency and returns the
Collatz-Wielandt bound of the Perron root, each mode's own loop taken exactly.
"""

from __future__ import annotations

import math

import numpy as np


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
    return np.where(inside, 0.0, np.sqrt(np.maximum(m, 0.0)) * (1 - 1e-12))


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
        # and on every loop, with its direction: E_ij = Gc_ij dh_j(i nu0_j) + (the rest)
        Gc = sum(MC[q] * np.take_along_axis(kap[q], order[:, :, 0], axis=1)[:, None, :]
                 for q in (0, 1, 2)) * (H0c / md.P * valid[:, :, 0])[:, None, :]
        self.Gc = Gc.astype(np.complex64)
        self.alpha = Gc[:, jj, jj]
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
        self.Gc = self.Gc[idx]
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
        self.self_bound = diag.max(axis=0)          # per mode, over the points
        rest = N - self.G[..., 0] * (Ts[:, :, 0] * self.has0)[:, None, :]
        N[:, jj, jj] = 0.0
        rho = _collatz(N / np.where(L > 0, L, 1.0)[:, :, None])
        rho = np.where((L > 0).all(axis=1), rho, np.inf)
        ell = np.where(self.has0, np.abs(beta) * _ratio_min(corners, dstar), 1.0)
        # a bound that is not a number proves nothing
        rho = np.where(np.isnan(rho), np.inf, rho)
        sel = np.flatnonzero(rho >= 1.0)           # the second test where the first fails
        if sel.size:
            with np.errstate(all="ignore"):
                closed = self._closed(sel, fw, fz, rest[sel], ell[sel], d0[sel], dstar[sel])
            rho[sel] = np.fmin(rho[sel], np.where(np.isnan(closed), np.inf, closed))
        return rho

    def _closed(self, sel, fw, fz, rest, ell, d0, dstar) -> np.ndarray:
        """The second test, with the couplings' phase.  Each mode's own loop is closed
        exactly: with ``E = Gc D + R`` (``D = diag(dh_j(i nu0_j))``, ``|R| <= rest``),
        ``I - E = [(I - Go T) - R (I - Gd D)^-1] (I - Gd D)``, ``Gd``/``Go`` the diagonal
        and off-diagonal parts of ``Gc`` and ``T = diag(t_j)``,
        ``t_j = dh_j / (1 - g_jj dh_j) = kappa (d - d0) / (d - d*)``: a Moebius image of
        the rectangle, held in a disc ``q_j + r_j u_j`` (radius exact over the
        rectangle).  With ``A0 = I - Go diag(q)``, ``I - E`` is nonsingular when every
        ``|1 - g_jj dh_j| >= ell_j > 0`` and the Perron root of
        ``|A0^-1 Go| diag(r) + |A0^-1| rest diag(1/ell)`` is below 1.  A phase-stabilised
        mode keeps its phase here: its closed own loop ``t_j`` is small, where the
        entrywise bound multiplies its open deviation by the couplings.
        """
        md = self.modes
        n = md.w0.size
        w0, c0 = md.w0[None, :], md.c0[None, :]
        nu0, has0 = self.nu0[sel], self.has0[sel]
        neg = nu0 < 0
        corners = [np.where(neg, c.conj(), c) for c in
                   _rect(nu0, w0, c0, (fw[0][None], fw[1][None]),
                         (fz[0][None], fz[1][None]))]
        g = self.alpha[sel]
        dst = np.where(neg, dstar.conj(), dstar)            # back to the signed plane
        kappa = -1.0 / np.where(d0 + g == 0, 1.0, d0 + g)
        t = np.linspace(0.0, 1.0, 9)[:-1]
        pts = np.concatenate([a[..., None] + t * (b - a)[..., None] for a, b in
                              zip(corners, corners[1:] + corners[:1])], axis=-1)
        with np.errstate(all="ignore"):
            tau = kappa[..., None] * (pts - d0[..., None]) / (pts - dst[..., None])
        q = (0.5 * (tau.real.max(-1) + tau.real.min(-1))
             + 0.5j * (tau.imag.max(-1) + tau.imag.min(-1)))
        # |t - q| = |kappa - q| |d - e| / |d - d*|,  e = (kappa d0 - q d*) / (kappa - q)
        kq = np.where(kappa - q == 0, 1e-300, kappa - q)
        e = (kappa * d0 - q * dst) / kq
        m = np.maximum.reduce([_seg_max(c - dst, f - c, e - dst) for c, f in
                               zip(corners, corners[1:] + corners[:1])])
        m = np.where(np.isfinite(m), m, np.inf)
        ok = has0 & (ell > 0) & np.isfinite(q)
        r = np.where(ok, np.abs(kq) * np.sqrt(m) * (1 + 1e-6), 0.0)
        q = np.where(ok, q, 0.0)
        Gc = self.Gc[sel].astype(np.complex128)
        jj = np.arange(n)
        Go = Gc.copy()
        Go[:, jj, jj] = 0.0
        A0 = np.eye(n)[None] - Go * q[:, None, :]
        with np.errstate(all="ignore"):
            Ainv = np.linalg.inv(A0)
        fin = np.isfinite(Ainv).all(axis=(1, 2))
        Ainv = np.where(fin[:, None, None], Ainv, 0.0)
        # Gc is kept in single precision: its error (1e-6 of it) joins the rest
        rest = rest + 1e-6 * np.abs(Gc) * (np.abs(q) + r)[:, None, :]
        inv_ell = np.where(has0, 1.0 / np.where(ell > 0, ell, 1.0), 1.0)
        Y = (np.abs(Ainv @ Go) * r[:, None, :]
             + (np.abs(Ainv) @ rest) * inv_ell[:, None, :])
        Y = np.where(np.isnan(Y), np.inf, Y)
        out = _collatz(Y) * (1 + 1e-6)
        cond = np.abs(A0).sum(axis=2).max(axis=1) * np.abs(Ainv).sum(axis=2).max(axis=1)
        good = fin & (cond < 1e8) & (ok | ~has0).all(axis=1)
        return np.where(good, out, np.inf)


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


def _band_grid(md: _Modes, k: float, which, cap: int = 4000) -> np.ndarray:
    """The bands of the modes ``which`` at scale ``k``, spaced at a third of the
    half-power width of their least damped point, folded into ``(0, pi/P]``."""
    fw, fz = md.box(k)
    pts = [np.zeros(0)]
    for w, lo, hi, c in zip(md.w0[which], (md.w0 * fw[0])[which], (md.w0 * fw[1])[which],
                            (md.c0 * fw[0] * fz[0])[which]):
        step = max(c / 6, 1e-9 * w)
        pts.append(np.linspace(0.98 * lo, 1.02 * hi, int(min(cap, (1.04 * hi - 0.96 * lo) / step
                                                              + 2))))
    nu = np.mod(np.concatenate(pts), md.Om)
    nyq = math.pi / md.P
    nu = np.where(nu > nyq, md.Om - nu, nu)
    return np.unique(np.clip(nu, 1e-5 * nyq, nyq))
