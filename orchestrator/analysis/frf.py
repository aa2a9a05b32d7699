"""Frequency responses of sampled loops given as matrices or python-control systems.

:func:`~orchestrator.analysis.spectra.transfer` gives the closed-loop transfers of a
scenario; these give them for a loop a design study assembles itself
(:mod:`orchestrator.analysis.sampled`):

* :func:`modal_frequency_response` -- many frequencies from one eigendecomposition;
* :func:`statespace_response` -- a python-control system evaluated on the unit circle;
* :func:`closed_loop_frf` -- a feedback loop closed in the frequency domain from the
  open-loop responses;
* :func:`transmissibility_bands` and :func:`isolation_bandwidth` -- where a loop
  isolates and where it amplifies.
"""

from __future__ import annotations

import numpy as np

__all__ = ["modal_frequency_response", "statespace_response", "closed_loop_frf",
           "transmissibility_bands", "isolation_bandwidth"]


def modal_frequency_response(A, B, C, freqs_hz, dt: float, D=None,
                             pairs: bool = False) -> np.ndarray:
    """Frequency response of ``x+ = A x + B u``, ``y = C x + D u`` in modal form.

    One eigendecomposition instead of one solve per frequency.  ``A`` must be
    diagonalisable: a free structure's rigid-body modes sample to Jordan blocks at
    ``z = 1``, so leave their states out first (:func:`~orchestrator.analysis.margins.
    without_states`) or read only outputs that do not see them (accelerations).

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Transition over one step ``dt``.
    B : ndarray, shape (n, n_in)
        Inputs, held over the step.
    C : ndarray, shape (n_out, n)
        Outputs.
    freqs_hz : array_like, shape (n_f,)
        Frequencies (Hz).
    dt : float
        Step (s).
    D : ndarray, shape (n_out, n_in), optional
        Feedthrough; none by default.
    pairs : bool
        Only output ``k`` per input ``k`` (``n_out == n_in``: collocated pairs, e.g.
        each stack's strain per its own force).

    Returns
    -------
    ndarray of complex, shape (n_f, n_out, n_in), or (n_f, n_out) with ``pairs``
        Output per unit input (output unit per input unit).
    """
    lam, V = np.linalg.eig(A)
    Bv, Cv = np.linalg.solve(V, B), C @ V
    z = np.exp(2j * np.pi * np.asarray(freqs_hz, float) * dt)
    R = 1.0 / (z[:, None] - lam[None, :])
    if pairs:
        H = np.einsum("oi,fi,io->fo", Cv, R, Bv)
        return H if D is None else H + np.diag(D)
    H = np.einsum("oi,fi,ij->foj", Cv, R, Bv)
    return H if D is None else H + D


def statespace_response(sys, freqs_hz) -> np.ndarray:
    """A discrete python-control system on the unit circle, ``z = exp(j 2 pi f dt)``.

    Parameters
    ----------
    sys : control.StateSpace
        Discrete system (its ``dt`` in s).
    freqs_hz : float or array_like, shape (n_f,)
        Frequencies (Hz).

    Returns
    -------
    ndarray of complex, shape (n_f, n_out, n_in)
    """
    return np.stack([np.asarray(sys(np.exp(2j * np.pi * f * sys.dt)))
                     for f in np.atleast_1d(freqs_hz)])


def closed_loop_frf(G, K, n_sensors: int, n_actuators: int, inp: int) -> np.ndarray:
    """Closed-loop response to one exogenous input, from open-loop responses.

    With ``u = K s`` (positive feedback: the law on the sensors ``s``, the first
    ``n_sensors`` outputs, driving the first ``n_actuators`` inputs),
    ``s = (I - G_su K)^-1 G_sd d`` and ``y = G_yd d + G_yu u``.

    Parameters
    ----------
    G : ndarray of complex, shape (n_f, n_out, n_in)
        Open-loop responses (e.g. :func:`statespace_response`).
    K : ndarray of complex, shape (n_f, n_actuators, n_sensors)
        The controller's response at each frequency (zero where a loop is open).
    n_sensors, n_actuators : int
        Outputs fed back, inputs driven.
    inp : int
        Column of ``G`` of the exogenous input ``d``.

    Returns
    -------
    ndarray of complex, shape (n_f, n_out)
        Every output per unit of ``d``, loops closed.
    """
    ns, nu = n_sensors, n_actuators
    out = []
    for g, k in zip(G, K):
        sens = np.linalg.solve(np.eye(ns) - g[:ns, :nu] @ k, g[:ns, inp])
        out.append(g[:, inp] + g[:, :nu] @ (k @ sens))
    return np.array(out)


def transmissibility_bands(freqs_hz, ratio) -> dict:
    """Where a loop isolates and where it amplifies.

    Parameters
    ----------
    freqs_hz : ndarray, shape (n,)
        Frequencies (Hz).
    ratio : ndarray, shape (n,)
        Open-loop over closed-loop magnitude of a response (-).

    Returns
    -------
    dict
        ``below_1_hz``: the frequency intervals where the transmissibility (closed over
        open) is below 1; ``max``, ``max_hz``: its largest value and where.
    """
    freqs = np.asarray(freqs_hz, float)
    t = 1.0 / np.asarray(ratio, float)
    below = np.r_[False, t < 1.0, False]
    edges = np.flatnonzero(np.diff(below.astype(int)))   # starts, then ends, alternating
    bands = [[float(freqs[a]), float(freqs[b - 1])] for a, b in zip(edges[::2], edges[1::2])]
    k = int(np.argmax(t))
    return {"below_1_hz": bands, "max": float(t[k]), "max_hz": float(freqs[k])}


def isolation_bandwidth(freqs_hz, ratio, f0_hz: float):
    """Upper end (Hz) of the band around ``f0_hz`` where open/closed stays above 1.

    Parameters
    ----------
    freqs_hz : ndarray, shape (n_f,)
        Frequencies, ascending (Hz).
    ratio : ndarray, shape (n_f,)
        Open- over closed-loop magnitude at ``freqs_hz`` (-).
    f0_hz : float
        A frequency the loop must isolate, e.g. the disturbance line (Hz).

    Returns
    -------
    float or None
        The highest frequency of ``freqs_hz`` (Hz) up to which ``ratio`` stays above 1
        from the one nearest ``f0_hz`` (``freqs_hz[-1]`` if it never falls to 1); None
        when ``f0_hz`` itself is not isolated.
    """
    k = int(np.argmin(np.abs(freqs_hz - f0_hz)))
    if ratio[k] <= 1.0:
        return None
    above = np.flatnonzero(ratio[k:] <= 1.0)
    return float(freqs_hz[k + above[0] - 1]) if above.size else float(freqs_hz[-1])
