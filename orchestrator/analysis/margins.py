"""Stability and margins of sampled loops given as matrices or as a stability test.

:meth:`LinearScenario.gain_margins` answers for a scenario; these answer for a loop
a design study assembles itself (:mod:`orchestrator.analysis.sampled`):

* :func:`spectral_radius`, :func:`without_states`, :func:`is_stable` -- stability of a
  transition matrix, neutral rigid-body poles set aside;
* :func:`siso_margins` -- gain and phase margins of one loop from its frequency response,
  and :func:`channel_margins` those of each stack loop of a decentralised design alone;
* :func:`loop_gain_margins_db` -- the margin of several loops scaled together and of each
  scaled alone with the others closed, from a stability test on the loop gains;
* :func:`poles_outside` -- the poles that leave the unit circle (which modes set a margin);
* :func:`band_damping` -- what a loop does to the damping of the modes in a band;
* :func:`best_direction` and :func:`scaled_to_margins` -- gain designs at a required
  margin: the best direction of a two-gain law, and per-loop gains scaled down until
  every loop keeps its margin.

The searches use :func:`~orchestrator.analysis.stability_margin_db` (factor doubled from
1, then geometric bisection).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .scenario import stability_margin_db

__all__ = ["spectral_radius", "without_states", "is_stable", "siso_margins",
           "channel_margins", "loop_gain_margins_db", "poles_outside", "band_damping",
           "best_direction", "scaled_to_margins"]


def spectral_radius(A) -> float:
    """Largest pole modulus of a discrete system matrix ``A``, shape (n, n) (-)."""
    return float(np.abs(np.linalg.eigvals(A)).max())


def without_states(A, states) -> np.ndarray:
    """``A`` without the rows and columns ``states``, e.g. the rigid-body states.

    The rigid-body modes of a free structure are double poles at z = 1 (Jordan blocks)
    that self-equilibrated loops neither see nor move; round-off of 1e-16 in their
    coupling splits such a pole by its square root, 1e-8, which a stability test would
    read as instability.  Removing their states first avoids that.

    Parameters
    ----------
    A : ndarray, shape (n, n)
    states : sequence of int
        States removed (:attr:`SampledStructure.rigid_states`).

    Returns
    -------
    ndarray, shape (n - len(states), n - len(states))
    """
    keep = np.setdiff1d(np.arange(A.shape[0]), states)
    return A[np.ix_(keep, keep)]


def is_stable(A, neutral_tol: float = 1e-6) -> bool:
    """All poles of ``A`` inside the unit circle, those within ``neutral_tol`` of 1 excepted.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Discrete transition matrix.
    neutral_tol : float
        Poles with ``|z - 1| <= neutral_tol`` (free-free rigid-body modes) are not tested.
    """
    ev = np.linalg.eigvals(np.asarray(A))
    return bool(np.all(np.abs(ev[np.abs(ev - 1) > neutral_tol]) < 1.0))


def siso_margins(freqs_hz, loop) -> tuple:
    """Gain and phase margins of one loop from its frequency response on a grid.

    Parameters
    ----------
    freqs_hz : ndarray, shape (n_f,)
        Ascending frequencies (Hz).
    loop : ndarray of complex, shape (n_f,)
        Loop transfer in the negative-feedback convention (the loop is unstable where it
        reaches -1); for a positive-feedback loop pass ``-L``.

    Returns
    -------
    gain_margin_db : float
        ``-20 log10 |L|`` at the worst -180 deg crossing (dB); ``inf`` if none.
    phase_margin_deg : float
        Phase above -180 deg at the ``|L| = 1`` crossing nearest to it (deg); ``inf`` if
        none.
    phase_crossover_hz, gain_crossover_hz : float or None
        Where those two are read (grid points, Hz).
    """
    f, h = freqs_hz, loop
    mag, ph = np.abs(h), np.unwrap(np.angle(h))
    gm, wgc = np.inf, None
    r = np.floor((ph + np.pi) / (2 * np.pi))
    for j in np.flatnonzero(r[1:] != r[:-1]):
        g = -20 * np.log10(mag[j])
        if g < gm:
            gm, wgc = float(g), float(f[j])
    pm, wpc = np.inf, None
    for j in np.flatnonzero((mag[1:] - 1) * (mag[:-1] - 1) < 0):
        p = (np.degrees(ph[j]) + 180.0) % 360.0
        p = p - 360.0 if p > 180 else p
        if abs(p) < abs(pm):
            pm, wpc = float(p), float(f[j])
    return gm, pm, wgc, wpc


def channel_margins(A, Bf, Cs, law, *, gain: float, force_per_volt: float, dt: float,
                    freqs_hz) -> list:
    """SISO margins of each stack loop of a decentralised design, the others open.

    Positive feedback (``u = K y``, ``ctrlfmu.analysis``): channel ``i``'s loop transfer
    is ``L = G_ii K z^-1 c h`` (the law's Eq. 11 sample, the stack's force per volt)
    and its margins are those of ``-L`` (:func:`siso_margins`).

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Sampled structure.
    Bf : ndarray, shape (n, n_c)
        Its stack force inputs (N).
    Cs : ndarray, shape (n_c, n)
        The sensor each channel's law reads.
    law : ctrlfmu.law.DiscreteLaw
        One sensor in, one command (V) out, the same on every channel.
    gain : float
        Factor on the law (-).
    force_per_volt : float
        Stack blocked force per volt (N/V).
    dt : float
        Sample period (s).
    freqs_hz : ndarray, shape (n_f,)
        Ascending frequency grid (Hz).

    Returns
    -------
    list of tuple
        Per channel :func:`siso_margins`' ``(gain margin dB, phase margin deg, phase
        crossover Hz, gain crossover Hz)``.
    """
    from ctrlfmu.analysis import frequency_response

    from .frf import modal_frequency_response

    f = np.asarray(freqs_hz, float)
    z = np.exp(2j * np.pi * f * dt)
    G = modal_frequency_response(A, Bf, Cs, f, dt, pairs=True)          # (n_f, n_c)
    k = frequency_response(law.with_gain(gain), f)[0, 0] * force_per_volt / z
    return [siso_margins(f, -(G[:, i] * k)) for i in range(G.shape[1])]


def loop_gain_margins_db(stable: Callable, gains, loops, *, limit: float = 64.0,
                         tol: float = 1.005, prefix: str = "loop") -> dict:
    """Gain margins of several loops: scaled together, and each alone, the others closed.

    Parameters
    ----------
    stable : callable
        ``stable(gains) -> bool``: is the loop stable with these gains, one per loop
        (a tuple of float)?
    gains : sequence of float
        The nominal gains, one per loop (loop ``k`` is ``gains[k - 1]``).
    loops : sequence of int
        The closed loops, numbered from 1.
    limit : float
        Largest factor searched (-); a loop still stable past it reports
        ``20 log10(limit)``.
    tol : float
        Ratio of the final bisection bracket (-), 1.005 for 0.5 %.
    prefix : str
        Key of loop ``k``: ``<prefix><k>``.

    Returns
    -------
    dict of str to float
        ``"all"``: the factor on every gain at once (dB; ``-inf`` if unstable at the
        nominal gains), and with more than one loop ``"<prefix><k>"`` for each, that gain
        alone scaled.
    """
    g = tuple(gains)
    beyond = 20 * np.log10(limit)
    out = {"all": stability_margin_db(lambda f: stable(tuple(f * x for x in g)), 2.0,
                                      limit, tol, beyond)}
    if len(loops) > 1:
        for k in loops:
            def alone(f, k=k):
                return stable(tuple(x * f if j == k else x for j, x in enumerate(g, 1)))

            out[f"{prefix}{k}"] = stability_margin_db(alone, 2.0, limit, tol, beyond)
    return out


def poles_outside(A, dt: float, neutral_tol: float = 1e-6) -> list:
    """The poles of a discrete loop on or outside the unit circle (upper half plane).

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Transition over one step ``dt``, e.g. with the gains just past a margin.
    dt : float
        Step (s).
    neutral_tol : float
        Poles within this of 1 (rigid body) are left out.

    Returns
    -------
    list of dict
        ``freq_hz`` (Hz) and ``abs_z`` of each, largest ``|z|`` first.
    """
    ev = np.linalg.eigvals(np.asarray(A))
    bad = ev[(np.abs(ev) >= 1.0) & (np.abs(ev - 1) > neutral_tol) & (ev.imag >= 0)]
    return [{"freq_hz": float(abs(np.angle(z)) / (2 * np.pi * dt)), "abs_z": float(abs(z))}
            for z in sorted(bad, key=lambda z: -abs(z))]


def band_damping(A_open, A_closed, dt: float, band=(5.0, 200.0), top: int = 5) -> dict:
    """Damping of the lightly damped poles (zeta < 0.5) in a band, open and closed loop.

    Parameters
    ----------
    A_open, A_closed : ndarray, shape (n, n) and (m, m)
        Transitions over one step ``dt`` without and with the loop.
    dt : float
        Step (s).
    band : (float, float)
        Pole frequency band (Hz).
    top : int
        Number of most damped closed-loop poles listed.

    Returns
    -------
    dict
        Largest open-loop and smallest closed-loop damping ratio, the number of
        closed-loop modes above 1 %, and the ``top`` most damped (Hz, ratio).
    """
    from ctrlfmu.analysis import mode_damping

    def poles(A):
        f, z = mode_damping(np.linalg.eigvals(A), dt)
        sel = (f >= band[0]) & (f <= band[1]) & (z < 0.5)
        return f[sel], z[sel]

    f0, z0 = poles(A_open)
    f1, z1 = poles(A_closed)
    best = np.argsort(z1)[::-1][:top]
    return {"band_hz": list(band), "open_loop_max_damping": float(z0.max()),
            "closed_loop_min_damping": float(z1.min()),
            "n_modes_above_1pct": int((z1 > 0.01).sum()),
            "closed_loop_most_damped": [{"f_hz": float(f1[i]), "zeta": float(z1[i])}
                                        for i in best]}


def best_direction(margin_db: Callable, score: Callable, n_dir: int = 36,
                   required_db: float = 6.0) -> tuple:
    """The best direction of a two-gain law at a required gain margin.

    For each direction ``(cos t, sin t)``, ``t`` evenly spaced over [0, 2 pi), the margin
    of the unit gains is found and the gains are set ``required_db`` below the stability
    limit; the direction whose gains score highest wins.

    Parameters
    ----------
    margin_db : callable
        ``margin_db(g1, g2) -> float``: gain margin of the loop with these gains (dB;
        ``-inf`` or ``inf`` when there is no finite limit: that direction is skipped).
    score : callable
        ``score(g1, g2) -> float``: what the gains achieve (e.g. a reduction in %).
    n_dir : int
        Number of directions scanned.
    required_db : float
        Margin kept (dB).

    Returns
    -------
    (score, g1, g2) : tuple of float
        ``(-inf, 0, 0)`` if no direction has a finite margin.
    """
    best = (-np.inf, 0.0, 0.0)
    for t in np.linspace(0, 2 * np.pi, n_dir, endpoint=False):
        k1, k2 = np.cos(t), np.sin(t)
        gm = margin_db(k1, k2)
        if not np.isfinite(gm):
            continue
        g = 10 ** ((gm - required_db) / 20)
        best = max(best, (score(g * k1, g * k2), g * k1, g * k2))
    return best


def scaled_to_margins(gains, joint_margin_db: Callable, loop_margins_db: Callable,
                      required_db: float = 6.0, tries: int = 8):
    """Per-loop gains in a fixed ratio, scaled until every loop keeps a margin.

    The gains are first scaled to ``required_db`` below their joint stability limit,
    then down (by the shortfall plus 0.05 dB, at most ``tries`` times) until the worst
    of ``loop_margins_db`` (e.g. :func:`loop_gain_margins_db`: the loops together and
    each alone) is at least ``required_db``.

    Parameters
    ----------
    gains : array_like, shape (n_loops,)
        The gains' ratio.
    joint_margin_db : callable
        ``joint_margin_db(gains) -> float`` (dB), all loops scaled together.
    loop_margins_db : callable
        ``loop_margins_db(gains) -> dict of str to float`` (dB).
    required_db : float
        Smallest margin allowed (dB).
    tries : int
        Largest number of scalings down.

    Returns
    -------
    tuple of float or None
        The gains; None when the ratio has no finite joint limit or does not reach the
        margin within ``tries``.
    """
    g = np.asarray(gains, float)
    gm = joint_margin_db(g)
    if not np.isfinite(gm):
        return None
    g = g * 10 ** ((gm - required_db) / 20)
    for _ in range(tries):
        worst = min(loop_margins_db(g).values())
        if worst >= required_db:
            return tuple(float(x) for x in g)
        g = g * 10 ** ((worst - required_db - 0.05) / 20)
    return None
