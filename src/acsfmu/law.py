"""The ACS law as a discrete linear system (pure, SI): the one truth of its linear model.

Per sample, with the inputs ``y = (roll, pitch, yaw, rate_x, rate_y, rate_z)`` read at
``t_n`` (:mod:`acsfmu.pid` without saturation)::

    xc+ = Ac xc + Bc y,      v = Cc xc + Dc y

with the state ``xc = [z (3), anti-alias filters (2 per input, in input order), notches
(2 per axis that has one), low-passes (2 per axis that has one)]`` and ``v`` the filtered
torque command (N m), applied one sample later (the law's computational delay is not in
this system: :func:`delayed_law` adds it).  With every filter off ``xc = z``.

:func:`law_state_space` serves the linear engine's ACS block
(:mod:`orchestrator.analysis.blocks`) and the design on the flexible plant
(:mod:`acsfmu.flexible`), so both read the law the FMU steps.
"""

from __future__ import annotations

import numpy as np

from acsfmu.filters import biquad_state_space

__all__ = ["law_state_space", "delayed_law", "axis_law"]


def law_state_space(config) -> tuple:
    """The law of ``config`` as ``(Ac, Bc, Cc, Dc)`` (see the module docstring).

    Parameters
    ----------
    config : AcsConfig
        Gains, sample time and filters.

    Returns
    -------
    Ac : ndarray, shape (nc, nc)
    Bc : ndarray, shape (nc, 6)
        From the six inputs (rad, rad/s).
    Cc : ndarray, shape (3, nc)
        To the filtered torque command (N m).
    Dc : ndarray, shape (3, 6)
    """
    T, g, f = config.sample_time, config.gains, config.filters
    kp, ki, kd = (np.asarray(v, float) * np.ones(3) for v in (g.kp, g.ki, g.kd))
    sections = ((6 if f.antialias_on else 0) + int(np.sum(f.notch_on))
                + int(np.sum(f.lowpass_on)))
    n = 3 + 2 * sections
    eye = np.eye(n + 6)              # a signal is a row over [xc (n); inputs (6)]
    M = np.zeros((n, n + 6))         # rows of [Ac Bc]
    k = 3

    def section(coef, signal):       # one biquad fed by signal: its output row
        nonlocal k
        a, b, c, d = biquad_state_space(coef)
        s = eye[k:k + 2]
        M[k:k + 2] = a @ s + np.outer(b, signal)
        k += 2
        return c @ s + d * signal

    inputs = [eye[n + j] for j in range(6)]
    if f.antialias_on:
        inputs = [section(f.antialias, x) for x in inputs]
    # z+ = z + T e, v = -(kp e + kd r + ki z), then the notch and the low-pass
    v = [-(kp[i] * inputs[i] + kd[i] * inputs[3 + i] + ki[i] * eye[i]) for i in range(3)]
    v = [section(f.notch[i], v[i]) if f.notch_on[i] else v[i] for i in range(3)]
    v = [section(f.lowpass[i], v[i]) if f.lowpass_on[i] else v[i] for i in range(3)]
    for i in range(3):
        M[i] = eye[i] + T * inputs[i]
    out = np.array(v)
    return M[:, :n], M[:, n:], out[:, :n], out[:, n:]


def delayed_law(config) -> tuple:
    """The law with its one-sample delay: state ``[xc, u (3)]``, output ``u``.

    Parameters
    ----------
    config : AcsConfig

    Returns
    -------
    A : ndarray, shape (nc + 3, nc + 3)
    B : ndarray, shape (nc + 3, 6)
    C : ndarray, shape (3, nc + 3)
        The torque applied over the sample (N m), the last three states.
    """
    Ac, Bc, Cc, Dc = law_state_space(config)
    nc = Ac.shape[0]
    A = np.zeros((nc + 3, nc + 3))
    A[:nc, :nc], A[nc:, :nc] = Ac, Cc
    B = np.vstack([Bc, Dc])
    C = np.hstack([np.zeros((3, nc)), np.eye(3)])
    return A, B, C


def axis_law(config, axis: int) -> tuple:
    """One axis of the law: inputs ``(angle, rate)`` of that axis, output its command.

    The law is decoupled by axis; the states that axis's inputs reach are kept.

    Parameters
    ----------
    config : AcsConfig
    axis : int
        0 roll (x), 1 pitch (y), 2 yaw (z).

    Returns
    -------
    (Ac, Bc, Cc, Dc)
        Shapes ``(k, k)``, ``(k, 2)``, ``(1, k)``, ``(1, 2)``.
    """
    Ac, Bc, Cc, Dc = law_state_space(config)
    cols = [axis, 3 + axis]
    keep = np.any(Bc[:, cols] != 0, axis=1) | (np.arange(Ac.shape[0]) == axis)
    while True:   # states reached from those
        more = keep | np.any(Ac[:, keep] != 0, axis=1)
        if (more == keep).all():
            break
        keep = more
    idx = np.flatnonzero(keep)
    return (Ac[np.ix_(idx, idx)], Bc[np.ix_(idx, cols)], Cc[axis:axis + 1, idx],
            Dc[axis:axis + 1, cols])
