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
from .certify_bounds import _Bound, _Modes, _band_grid, _grid, dh_bound
from .certify_model import _Components, _model_check, _StructureResponse

__all__ = ["certify", "loop_members", "dh_bound"]

_CHUNK = 256
_WORKERS = 2          # threads over the frequency chunks


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


def _moving_radius(ev) -> float:
    moving = np.abs(ev - 1.0) > 1e-6
    return float(np.abs(ev[moving]).max()) if moving.any() else 0.0


def _refuse(text: str, **extra) -> dict:
    return {"margin_guaranteed": None, "margin_partial": None, "complete": False,
            "certificate": text, **extra}


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
    names = (", ".join(members) if len(members) <= 6 else
             f"{len(members)} instances ({', '.join(members[:4])}, ...)")
    what = (f"modal frequency and damping factors of {U.size} modes of {S!r}; loops "
            f"{names or 'none'} at {P:g} s")
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
    self_bound = np.zeros(U.size)

    def chunk(nu_c, k_test, k_box):
        z = np.exp(1j * nu_c * P)
        K, P0 = Kresp(z, ui, yi), sresp(z) @ gmap
        M = np.einsum("nu,zuy->zny", beta, np.linalg.solve(np.eye(len(u_ch)) - K @ P0, K))
        b = _Bound(md, nu_c, M, k_box)
        return b, b.rho(k_test) >= 1.0

    def scan(nu, k_test, k_box):
        """The grid points of ``nu`` not proven at ``k_test`` (their bounds kept), each
        chunk with the largest scale known to hold on it.  The chunks are independent:
        two threads share them (numpy releases the interpreter in its kernels)."""
        from ._threads import blas_pool

        kept = []
        starts = range(0, nu.size, _CHUNK)
        with blas_pool(_WORKERS) as pool:
            done = pool.map(lambda c0: chunk(nu[c0:c0 + _CHUNK], k_test, k_box), starts)
            for b, fail in done:
                np.maximum(self_bound, b.self_bound, out=self_bound)
                if fail.any():
                    b.k_ok = 0.0
                    kept.append(b.take(fail))
        return kept

    def bisect(kept, lo, hi):
        from ._threads import blas_pool

        with blas_pool(_WORKERS) as pool:
            while hi - lo > tol * max(hi, 1e-3):
                mid = 0.5 * (lo + hi)
                # proven there already where k_ok >= mid (the bound grows with k); the
                # rest in pairs, the least proven first, until one fails
                todo = [b for b in sorted(kept, key=lambda b: b.k_ok) if mid > b.k_ok]
                bad = False
                for i in range(0, len(todo), _WORKERS):
                    group = todo[i:i + _WORKERS]
                    fails = list(pool.map(lambda b: bool((b.rho(mid) >= 1.0).any()), group))
                    for b, f in zip(group, fails):
                        if not f:
                            b.k_ok = mid
                    if any(fails):
                        bad = True
                        break
                lo, hi = (lo, mid) if bad else (mid, hi)
        return lo, hi

    nu = _grid(md, k_hi, ev_cl)
    say(f"certificate: {nu.size} frequencies, {U.size} modes, k up to {k_hi:.3g}")
    kept = scan(nu, k_hi, k_hi)
    k_g, hi = (k_hi, k_hi) if not kept else bisect(kept, 0.0, k_hi)
    n_freq = nu.size
    # refine the bands of the modes whose own loop can come near 1 (the bound of their
    # own term, at the largest scale, above 0.3 somewhere on the grid: elsewhere it
    # keeps |1 - E_jj| >= 0.7 and nothing narrow is missed), at the spacing of the
    # narrowest resonance in the box at the scale reached, until that scale holds
    tight = self_bound >= 0.3
    for _ in range(6):
        if k_g <= 0 or not tight.any():
            break
        fine = _band_grid(md, min(k_hi, k_g * (1 + 2 * tol)), tight)
        n_freq += fine.size
        say(f"certificate: k {k_g:.4g} on {n_freq - fine.size} frequencies; checking "
            f"{fine.size} more in the bands of {int(tight.sum())} modes")
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
    out = _result(k_g, what, opened, P, nu.size, worst, mcheck, t0,
                  f"proven stable for every point of the set scaled by {k_g:.4g} about "
                  f"nominal ({what}), on {nu.size} frequencies")
    # the modes whose own loop comes nearest to 1: where a search should look
    top = [int(j) for j in np.argsort(self_bound)[::-1][:16] if self_bound[j] >= 0.3]
    if worst is not None:      # and the modes nearest the tightest frequency
        top += [int(j) for j in np.argsort(np.abs(md.w0 - 2 * math.pi * worst))[:3]]
    out["tight_modes"] = [int(U[j]) for j in dict.fromkeys(top)]
    return out


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

