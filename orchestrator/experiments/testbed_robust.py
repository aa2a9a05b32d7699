"""The testbed isolation law over the testbed's uncertainty, and its design within the
paper's structure.

The uncertain set (the testbed's, as the robustness work states it for a lightly damped
truss): every flexible mode's frequency (above 1 Hz) within x0.95-1.05 and its damping
ratio within x0.5-2, the rigid-body and suspension modes left as they are.
:func:`perturbed_plants` gives the sampled plant
(:func:`~orchestrator.experiments.testbed_design.linear_plant`) at its nine common
corners (every mode at the same factors) and at ``n_random`` points drawn per mode
(uniform in frequency, log-uniform in damping, seeded); :func:`stability_limit` is the
largest factor on a law's gains that keeps one plant's sampled closed loop stable, and
:func:`robust_factor` the factor that keeps ``margin_db`` below the smallest limit over the
set.  This is a sampled check (corners and random points), not a certificate: a point of
the set outside the sample could be worse.

:func:`design_within_structure` is the design of the mount-#3 law within the paper's
structure (two zeros at 100 rad/s, two poles at 1 rad/s, a 2nd-order Butterworth
band-pass, 1 kHz): for each pair of band-pass corners, each gain direction (payload,
bus) scaled to ``margin_db`` below the smallest stability limit over the plants it is
given, the direction removing the most boresight jitter at the harmonics on the nominal
plant.  Slow (minutes per corner pair): the numbers are in docs/eos_experiments.md.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..analysis.margins import is_stable
from .testbed_design import (DT, HARMONICS, _design_law, boresight_reduction, closed_loop,
                             linear_plant, per_mount, plant_frf)

#: Factors of the uncertain set: modal frequency (low, high) and damping ratio (low, high).
FREQUENCY_RANGE = (0.95, 1.05)
DAMPING_RANGE = (0.5, 2.0)
#: Modes below this frequency (Hz: rigid body, suspension) are not perturbed.
FLEXIBLE_ABOVE_HZ = 1.0


def perturbed_plants(model, n_random=0, seed=0) -> dict:
    """The sampled plant at the set's common corners and ``n_random`` per-mode points.

    Parameters
    ----------
    model : ReducedModel
        The nominal reduced testbed
        (:func:`~orchestrator.experiments.testbed_design.linear_model`).
    n_random : int
        Points drawn per mode (frequency uniform, damping log-uniform in their ranges).
    seed : int
        Seed of the draws.

    Returns
    -------
    dict of str to control.StateSpace
        ``"f<factor> z<factor>"`` for the nine corners (``"f1.0 z1.0"`` the nominal) and
        ``"random <i>"``.
    """
    flex = model.omega > 2 * np.pi * FLEXIBLE_ABOVE_HZ

    def at(ff, zz):
        ff, zz = np.where(flex, ff, 1.0), np.where(flex, zz, 1.0)
        return linear_plant(dataclasses.replace(model, omega=model.omega * ff,
                                                modal_damping=model.modal_damping * ff * zz))

    fl, fh = FREQUENCY_RANGE
    zl, zh = DAMPING_RANGE
    out = {f"f{f:g} z{z:g}": at(f, z) for f in (fl, 1.0, fh) for z in (zl, 1.0, zh)}
    rng = np.random.default_rng(seed)
    for i in range(n_random):
        out[f"random {i}"] = at(rng.uniform(fl, fh, model.n_modes),
                                np.exp(rng.uniform(np.log(zl), np.log(zh), model.n_modes)))
    return out


def stability_limit(plant, mounts, gain=1.0, law=None, tol=1.002) -> float:
    """The largest factor on the laws' gains at which the sampled closed loop is stable.

    Doubling or halving from 1, then bisection to ``tol``; 0 if even ``2**-20`` is
    unstable, ``2**20`` past it.

    Parameters
    ----------
    plant : control.StateSpace
        Discrete plant (:func:`~orchestrator.experiments.testbed_design.linear_plant`).
    mounts : sequence of int
        The mounts whose loops are closed.
    gain : float or sequence of float
        Factor on the design law, per mount or one for all (unused with ``law``).
    law : control.StateSpace, optional
        A law for every mount instead of the design law (its gains scaled).
    tol : float
        Ratio of the bracket at which the bisection stops.
    """
    # deferred: python-control takes about 1 s to load
    import control

    if law is None:
        base = np.array(per_mount(gain))

        def stable(g):
            return is_stable(closed_loop(plant, mounts, tuple(g * base)).A)
    else:
        def stable(g):
            return is_stable(closed_loop(plant, mounts, law=control.ss(
                law.A, law.B, g * law.C, g * law.D, DT)).A)
    g = 1.0
    if stable(g):
        while stable(2 * g):
            g *= 2
            if g >= 2.0 ** 20:
                return g
        lo, hi = g, 2 * g
    else:
        while not stable(g / 2):
            g /= 2
            if g <= 2.0 ** -20:
                return 0.0
        lo, hi = g / 2, g
    while hi / lo > tol:
        m = np.sqrt(lo * hi)
        lo, hi = (m, hi) if stable(m) else (lo, m)
    return float(lo)


def robust_factor(plants, mounts, gain=1.0, margin_db=6.0) -> dict:
    """The factor on ``gain`` that keeps ``margin_db`` over every plant of the set.

    Parameters
    ----------
    plants : dict of str to control.StateSpace
        :func:`perturbed_plants`.
    mounts : sequence of int
        The mounts whose loops are closed.
    gain : float or sequence of float
        Factor on the design law, per mount or one for all.
    margin_db : float
        Gain margin kept at the worst plant (dB).

    Returns
    -------
    dict
        ``factor`` (-), ``worst`` (the plant that sets it), ``limits`` (each plant's
        :func:`stability_limit` of ``gain``) and ``margin_db`` of ``gain`` itself over
        the set (dB, negative: unstable somewhere in it).
    """
    limits = {k: stability_limit(p, mounts, gain) for k, p in plants.items()}
    worst = min(limits, key=limits.get)
    lim = limits[worst]
    return {"factor": lim * 10 ** (-margin_db / 20), "worst": worst, "limits": limits,
            "margin_db": 20 * np.log10(lim) if lim > 0 else -np.inf}


def design_within_structure(plant, plants, bands, n_dir=18, margin_db=6.0, mount=3) -> list:
    """The paper's law at one mount: best corners and gain direction at a robust margin.

    Parameters
    ----------
    plant : control.StateSpace
        The nominal plant (the reduction is measured on it).
    plants : sequence of control.StateSpace
        The plants whose smallest stability limit sets each direction's scale (the
        nominal and the set's worst corners, e.g. :func:`perturbed_plants` at damping
        x0.5).
    bands : sequence of (float, float)
        Band-pass corners tried (Hz).
    n_dir : int
        Directions over half a turn; each is tried with both signs.
    margin_db : float
        Margin below the smallest stability limit (dB).
    mount : int
        The mount.

    Returns
    -------
    list of dict
        Per band: ``band``, ``gains`` (payload, bus; V per m/s^2 at the band centre) and
        ``reduction_pct`` (nominal plant, steady state at the harmonics).
    """
    Gh = plant_frf(plant, list(HARMONICS))
    out = []
    for band in bands:
        best = {"band": tuple(band), "gains": (0.0, 0.0), "reduction_pct": 0.0}
        for t in np.linspace(0.0, np.pi, n_dir, endpoint=False):
            for sign in (1.0, -1.0):
                kp, kb = sign * np.cos(t), sign * np.sin(t)
                law = _design_law(kp, kb, band=band)
                lim = min(stability_limit(p, (mount,), law=law) for p in plants)
                if lim <= 0:
                    continue
                s = lim * 10 ** (-margin_db / 20)
                red = boresight_reduction(plant, (mount,), law=_design_law(s * kp, s * kb,
                                                                           band=band), Gh=Gh)
                if red > best["reduction_pct"]:
                    best = {"band": tuple(band), "gains": (s * kp, s * kb),
                            "reduction_pct": red}
        out.append(best)
    return out
