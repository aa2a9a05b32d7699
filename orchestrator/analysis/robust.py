"""Robust stability of a scenario's loops over a modal uncertainty set.

The set is a campaign's ``[uncertainty]`` table (:mod:`orchestrator.campaign.spec_uncertainty`):
factors on the modal frequencies and damping ratios (per mode or common) and on
controller gains, each within its distribution's bounds; the amplitudes and phases of
sources do not move a pole and are left out.  Every loop is the exact sampled loop of
:func:`~orchestrator.analysis.linearize` (all rates, delays and holds; the modes above a
loop's Nyquist frequency alias as they do), with the sample's structure in place, and
stability is read from its poles over one hyperperiod.

:func:`robust_stability` answers with

* ``sampled``: ``samples`` random points of the set, the unstable count, its one-sided
  95 % Clopper-Pearson upper bound, the worst ``|z|``, and for the worst samples what
  drives them: the loops whose opening makes the sample stable, and the modes that carry
  the unstable pole (their share of its eigenvector);
* ``corners``: every damping bound (all modes at the low, then the high factor) across a
  grid of common frequency factors;
* ``margin_found``: the smallest scale ``k`` of the set about nominal (each factor's range
  ``[1 - k (1 - low), 1 + k (high - 1)]``) at which a destabilising point was found, by a
  search along the rays through the worst samples and corners, confirmed by eigenvalues;
  with that point;
* ``margin_guaranteed``: the largest ``k`` proven stable, by the certificate of
  :mod:`orchestrator.analysis.certify` (zero exclusion of the sampled-data loop over the
  modes' value sets); ``certificate`` says what it covers.  The true margin lies between
  the two: ``margin_guaranteed <= k* <= margin_found``.
"""

from __future__ import annotations

import math

import numpy as np

from .blocks import AnalysisError
from ._threads import map_threads
from .modalset import UncertainSet, _factors, loop_at, uncertain_set
from .uncertainty import UncertaintyError, draw

__all__ = ["UncertainSet", "uncertain_set", "robust_stability", "loop_at", "pole_radius"]

_RIGID_TOL = 1e-6
_PAIR = 2            # loops judged side by side (threads, one BLAS thread each)


def pole_radius(lin, like=None) -> float:
    """Largest pole modulus over one hyperperiod, rigid-body poles at 1 left out.

    Parameters
    ----------
    lin : LinearScenario
    like : FastResponse, optional
        The nominal loop compiled (:class:`~orchestrator.analysis.fast.FastResponse`):
        a sample's loop shares its layout and its map is taken by doubling.

    Returns
    -------
    float
    """
    from .fast import FastResponse
    from .steady import loop_eigenvalues

    fr = FastResponse(lin, [], strict=False, like=like)
    ev = loop_eigenvalues(fr.period_map())
    moving = np.abs(ev - 1.0) > _RIGID_TOL
    return float(np.abs(ev[moving]).max()) if moving.any() else 0.0


def _unstable_pole(lin) -> tuple:
    """The largest moving pole of the lifted map and its eigenvector (lifted layout)."""
    ev, vecs = np.linalg.eig(lin.lifted())
    moving = np.abs(ev - 1.0) > _RIGID_TOL
    i = int(np.argmax(np.where(moving, np.abs(ev), -1.0)))
    return ev[i], vecs[:, i]


def _scaled(uset, values: dict, k: float) -> dict:
    """A point moved to ``k`` times its distance from nominal (factors about 1)."""
    return {name: 1.0 + k * (np.asarray(v, float) - 1.0) for name, v in values.items()}


def clopper_pearson_upper(k: int, n: int, assurance: float = 0.95) -> float:
    """One-sided upper bound on a probability from ``k`` events in ``n`` trials.

    Parameters
    ----------
    k, n : int
        Events and trials.
    assurance : float
        Confidence of the bound (-).

    Returns
    -------
    float
    """
    from scipy.stats import beta

    return 1.0 if k >= n else float(beta.ppf(assurance, k + 1, n - k))


def _drivers(lin, lin_p, uset, groups) -> dict:
    """What drives an unstable sample: loops whose opening stabilises it, and modes."""
    z, vec = _unstable_pole(lin_p)
    loops = []
    for name, chans in groups.items():
        insts = sorted({c.split(".", 1)[0] for c in chans})
        if pole_radius(lin_p.opened(insts)) < 1.0:
            loops.append(name)
    sx = lin.slots[uset.structure][0]
    n_m = lin.blocks[uset.structure].model.n_modes
    v = vec[sx]
    share = np.abs(v[:n_m]) ** 2 + np.abs(v[n_m:2 * n_m]) ** 2
    total = share.sum()
    top = np.argsort(share)[::-1][:3]
    f0 = lin.blocks[uset.structure].model.omega / (2 * math.pi)
    T = lin.T
    return {"pole_freq_hz": float(abs(np.angle(z)) / (2 * math.pi * T)),
            "abs_z": float(abs(z)),
            "loops": loops,
            "modes": [{"mode": int(j + 1), "nominal_hz": float(f0[j]),
                       "share": float(share[j] / total) if total > 0 else 0.0}
                      for j in top]}


def robust_stability(lin, items, *, samples: int = 200, seed: int = 0, grid: int = 5,
                     worst: int = 3, k_max: float = 4.0, progress=None,
                     certificate: bool = True, say=None) -> dict:
    """Sampled, corner and found-margin robust stability (see the module docstring).

    Parameters
    ----------
    lin : LinearScenario
        The nominal loop.
    items : sequence of Uncertain
        The uncertainty set (the kinds that do not move poles are left out).
    samples : int
        Random points drawn (>= 1).
    seed : int
        Seed of the draws.
    grid : int
        Common frequency factors across the set's range for the corners (>= 2).
    worst : int
        Worst samples whose drivers are named and whose rays are searched.
    k_max : float
        Largest scale of the set searched for a destabilising point (-).
    progress : callable, optional
        ``progress(done, total)`` after each evaluation.
    certificate : bool
        Compute ``margin_guaranteed`` (:func:`~orchestrator.analysis.certify.certify`).
    say : callable, optional
        ``say(text)`` for the certificate's stages.

    Returns
    -------
    dict
        JSON-ready: ``samples``, ``unstable``, ``unstable_p_upper``, ``worst_abs_z``,
        ``nominal_abs_z``, ``corners``, ``margin_guaranteed``, ``certificate``,
        ``margin_found``, ``found_point``, ``drivers``.
    """
    from .loops import loop_groups

    if not (isinstance(samples, int) and samples >= 1):
        raise UncertaintyError(f"samples is {samples!r}; expected a whole number >= 1")
    if not (isinstance(grid, int) and grid >= 2):
        raise UncertaintyError(f"grid is {grid!r}; expected a whole number >= 2")
    uset = uncertain_set(lin, items)
    model = lin.blocks[uset.structure].model
    total = samples + 2 * grid + 1
    done = [0]

    def tick():
        done[0] += 1
        if progress:
            progress(done[0], total)

    from .fast import FastResponse

    like = FastResponse(lin, [], strict=False)
    r0 = pole_radius(lin, like)
    tick()
    d = draw(list(uset.items), samples, seed, model.omega / (2 * math.pi))
    radii = np.empty(samples)
    # independent loops: two threads (eigenvalues and products release the interpreter)
    for s0 in range(0, samples, _PAIR):
        part = range(s0, min(samples, s0 + _PAIR))
        radii[list(part)] = map_threads(
            lambda s: pole_radius(loop_at(lin, uset, {name: d.values[name][s]
                                                      for name in d.values}), like),
            part, workers=_PAIR)
        for _ in part:
            tick()
    unstable = int((radii >= 1.0).sum())
    # corners: every damping bound over a grid of common frequency factors
    fw_items = [it for it in uset.items if it.kind == "modal_frequency"]
    zt_items = [it for it in uset.items if it.kind == "modal_damping"]
    lo_w = min([uset.bounds(it.name)[0] for it in fw_items], default=1.0)
    hi_w = max([uset.bounds(it.name)[1] for it in fw_items], default=1.0)
    corners = []
    for fw in np.linspace(lo_w, hi_w, grid):
        rs = map_threads(lambda side, fw=fw: pole_radius(
            loop_at(lin, uset, _point(uset, d, fw, side)), like), (0, 1), workers=_PAIR)
        for side, r in zip((0, 1), rs):
            corners.append({"frequency_factor": float(fw),
                            "damping": "low" if side == 0 else "high",
                            "damping_factor": [uset.bounds(it.name)[side] for it in zt_items],
                            "abs_z": r, "stable": r < 1.0})
            tick()
    groups = loop_groups(lin)
    order = np.argsort(radii)[::-1][:worst]
    drivers = []
    for s in order:
        if radii[s] < 1.0:
            break
        vals = {name: d.values[name][s] for name in d.values}
        dr = _drivers(lin, loop_at(lin, uset, vals), uset, groups)
        drivers.append({"sample": int(s), **dr})
    # found margin: rays through the worst samples and corners
    rays = [{name: d.values[name][s] for name in d.values} for s in order]
    rays += [_point(uset, d, c["frequency_factor"], 0 if c["damping"] == "low" else 1)
             for c in sorted(corners, key=lambda c: -c["abs_z"])[:worst]]
    cert = ({"margin_guaranteed": None, "certificate": "not computed (not asked for)"}
            if not certificate else _certificate(lin, uset, k_max, say))
    # and through one mode alone at its corners, for the modes whose own loop the
    # certificate found tightest (random points seldom put one mode at a corner)
    # (searched first: a low found margin early stops the other rays sooner)
    rays = [r for j in cert.get("tight_modes", []) for r in _mode_corners(uset, d, j)] + rays
    # below a whole-loop certificate no point can be unstable: the rays start there
    k0 = cert["margin_guaranteed"] or 0.0
    found, point = math.inf, None
    for i in range(0, len(rays), _PAIR):     # two rays at a time, each below the found
        pair = rays[i:i + _PAIR]
        ks = map_threads(lambda v, below=found: _ray_limit(lin, uset, v, k_max, below, like,
                                                           start=k0), pair, workers=_PAIR)
        for vals, k in zip(pair, ks):
            if k < found:
                found, point = k, _scaled(uset, vals, k * 1.001)
    found_point = None
    if point is not None:
        r = pole_radius(loop_at(lin, uset, point), like)
        found_point = {"k": found * 1.001, "abs_z": r,
                       "factors": {n: np.atleast_1d(v).tolist() for n, v in point.items()}}
    mg = cert["margin_guaranteed"]
    return {"samples": samples, "unstable": unstable,
            "unstable_p_upper": clopper_pearson_upper(unstable, samples),
            "worst_abs_z": float(radii.max()), "nominal_abs_z": r0,
            "nominal_stable": r0 < 1.0, "corners": corners,
            "margin_guaranteed": mg,
            "certificate": cert["certificate"],
            "certificate_detail": {k: v for k, v in cert.items()
                                   if k not in ("margin_guaranteed", "certificate")},
            "margin_gap": (found - mg if mg is not None and math.isfinite(found) else None),
            "margin_found": found if math.isfinite(found) else None,
            "found_point": found_point, "drivers": drivers,
            "structure": uset.structure,
            "parameters": [it.name for it in uset.items]}


def _certificate(lin, uset, k_max: float, say) -> dict:
    """:func:`~orchestrator.analysis.certify.certify`, its refusals as a reason."""
    from ._threads import blas_threads_kept, one_blas_thread
    from .certify import certify

    try:
        # many small products: one BLAS thread each (two fight over busy cores)
        with blas_threads_kept():
            one_blas_thread()
            return certify(lin, uset, k_max=k_max, progress=say)
    except AnalysisError as exc:
        return {"margin_guaranteed": None, "certificate": f"not computed: {exc}"}


def _mode_corners(uset, d, mode: int) -> list:
    """Points with mode ``mode`` alone at its low damping bound and either frequency
    bound (per-mode parameters only; none when a parameter is common to modes)."""
    if not all(it.kind == "gain" or it.per_mode for it in uset.items):
        return []
    out = []
    for side in (0, 1):
        vals = {}
        for it in uset.items:
            v = np.ones(d.values[it.name].shape[1])
            if it.kind != "gain":
                where = np.flatnonzero(uset.modes[it.name] == mode)
                if it.kind == "modal_frequency":
                    v[where] = uset.bounds(it.name)[side]
                else:
                    v[where] = uset.bounds(it.name)[0]
            vals[it.name] = v
        out.append(vals)
    return out


def _point(uset, d, fw: float, side: int) -> dict:
    """Every mode at frequency factor ``fw`` and damping bound ``side`` (0 low, 1 high);
    gains at nominal."""
    vals = {}
    for it in uset.items:
        k = d.values[it.name].shape[1]
        if it.kind == "modal_frequency":
            vals[it.name] = np.full(k, fw)
        elif it.kind == "modal_damping":
            vals[it.name] = np.full(k, uset.bounds(it.name)[side])
        else:
            vals[it.name] = np.ones(k)
    return vals


def _ray_limit(lin, uset, vals, k_max: float, below: float, like=None,
               tol: float = 0.01, start: float = 0.0, step: float = 0.1) -> float:
    """Smallest scale along the ray through ``vals`` at which the loop is unstable
    (``inf`` if none up to ``k_max``; the search stops at ``below``).  The ray is stepped
    by ``step``: instability along a ray can be a window (a mode moved through a phase
    band and out again), which a coarser step steps over."""
    prev = start
    for k in np.arange(start + step, min(k_max, below) + 1e-9, step):
        pt = _scaled(uset, vals, k)
        if any(np.any(v <= 0) for n, v in pt.items()
               if any(it.name == n and it.kind != "gain" for it in uset.items)):
            break    # a factor at zero: outside any physical set
        if pole_radius(loop_at(lin, uset, pt), like) >= 1.0:
            a, b = prev, k
            while b - a > tol * b:
                m = 0.5 * (a + b)
                rm = pole_radius(loop_at(lin, uset, _scaled(uset, vals, m)), like)
                a, b = (a, m) if rm >= 1.0 else (m, b)
            return b
        prev = k
    return math.inf
