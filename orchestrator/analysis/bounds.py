"""Bounds a design is measured against: upper bounds and least-squares optima.

:func:`~orchestrator.analysis.ceiling` answers for a scenario; these answer from the
responses a design study computes itself (:mod:`orchestrator.analysis.frf`):

* :func:`harmonic_reduction_pct` -- the RMS reduction over disturbance lines;
* :func:`harmonic_ceiling` -- the most any controller at the chosen actuators could
  remove at those lines (``optimal``: the least-squares best commands, the upper bound),
  and what cancelling its sensors gives (``cancel``: infinite gain; not a bound);
* :func:`best_real_gain` -- the best real gain on one fixed correction (the most a
  feedforward path of a given shape could do);
* :func:`least_squares_inputs` and :func:`least_squares_records` -- per-frequency
  regularised least-squares inputs that cancel a recorded response, and the records
  they give (non-causal, periodic, swept over the regularisation), and
  :func:`record_ceiling` the best of them: exact cancellation (the upper bound) and the
  best within limits (achievable within them, not a bound on them).
"""

from __future__ import annotations

import numpy as np

__all__ = ["harmonic_reduction_pct", "harmonic_ceiling", "best_real_gain",
           "least_squares_inputs", "least_squares_records", "record_ceiling"]


def harmonic_reduction_pct(open_loop, closed_loop, amplitudes) -> float:
    """Reduction (%) of the RMS of some outputs over harmonic disturbance lines.

    Parameters
    ----------
    open_loop, closed_loop : ndarray of complex, shape (n_h, n_y)
        Response of the outputs per unit disturbance at each line, without and with
        control (output unit per disturbance unit).
    amplitudes : ndarray, shape (n_h,)
        Disturbance amplitude of each line (its unit).

    Returns
    -------
    float
        ``100 (1 - rms_closed / rms_open)`` (%), the lines weighted by their amplitudes.
    """
    a = np.asarray(amplitudes, float)
    num = np.sum(a[:, None] ** 2 * np.abs(closed_loop) ** 2)
    den = np.sum(a[:, None] ** 2 * np.abs(open_loop) ** 2)
    return float(100 * (1 - np.sqrt(num / den)))


def harmonic_ceiling(Gd, Gu, amplitudes, Sd=None, Su=None) -> dict:
    """The most any controller at some actuators could remove at harmonic lines.

    ``optimal``: the least-squares best actuator commands at each line (no controller,
    causal or not, does better in steady state: the upper bound); ``cancel`` (with
    ``Sd``, ``Su``): the commands that hold the sensors at exactly zero, what a loop of
    infinite gain on them would do -- a reference point, not a bound (a finite-gain law
    can remove more).

    Parameters
    ----------
    Gd : ndarray of complex, shape (n_h, n_y)
        Performance outputs per unit disturbance at each line.
    Gu : ndarray of complex, shape (n_h, n_y, n_u)
        Performance outputs per unit actuator command.
    amplitudes : ndarray, shape (n_h,)
        Disturbance amplitude of each line.
    Sd : ndarray of complex, shape (n_h, n_s), optional
        Sensors per unit disturbance.
    Su : ndarray of complex, shape (n_h, n_s, n_u), optional
        Sensors per unit actuator command (square: solved; else least squares).

    Returns
    -------
    dict of str to float
        ``optimal`` and, with sensors, ``cancel``: reduction of the RMS (%),
        :func:`harmonic_reduction_pct`.
    """
    a = np.asarray(amplitudes, float)
    den = null = opt = 0.0
    for i in range(len(a)):
        b, Hb = Gd[i], Gu[i]
        w = np.linalg.lstsq(Hb, -b, rcond=None)[0]
        den += a[i]**2 * np.sum(np.abs(b) ** 2)
        opt += a[i]**2 * np.sum(np.abs(b + Hb @ w) ** 2)
        if Sd is not None:
            S = Su[i]
            v = (-np.linalg.solve(S, Sd[i]) if S.shape[0] == S.shape[1]
                 else np.linalg.lstsq(S, -Sd[i], rcond=None)[0])
            null += a[i]**2 * np.sum(np.abs(b + Hb @ v) ** 2)
    out = {"optimal": float(100 * (1 - np.sqrt(opt / den)))}
    if Sd is not None:
        out["cancel"] = float(100 * (1 - np.sqrt(null / den)))
    return out


def best_real_gain(b, e) -> tuple:
    """The real ``k`` minimising ``|b + k e|``, and the reduction it gives.

    Parameters
    ----------
    b : ndarray of complex, shape (n,)
        The response to reduce (e.g. outputs at the disturbance lines, each weighted by
        its amplitude).
    e : ndarray of complex, shape (n,)
        What a unit gain adds to it (e.g. a feedforward path of fixed shape).

    Returns
    -------
    (k, reduction_pct) : tuple of float
        The gain and ``100 (1 - |b + k e| / |b|)`` (%).
    """
    b, e = np.ravel(b), np.ravel(e)
    er = np.concatenate([e.real, e.imag])
    k = -np.dot(np.concatenate([b.real, b.imag]), er) / np.dot(er, er)
    return float(k), float(100 * (1 - np.linalg.norm(b + k * e) / np.linalg.norm(b)))


def least_squares_inputs(G, Y, rhos):
    """Per-frequency inputs that cancel a response best, for each regularisation.

    ``F = -(G^H G + rho s I)^-1 G^H Y`` at each frequency, ``s`` the median of
    ``trace(G^H G) / n_in`` over the frequencies (so ``rho`` is relative); ``rho = 0``
    gives the minimum-norm inputs ``F = -G^+ Y``.  On the DFT grid of a record this is
    the non-causal, periodic least-squares optimum: a bound, not a controller.

    Parameters
    ----------
    G : ndarray of complex, shape (n_f, n_y, n_in)
        Outputs per unit input at each frequency.
    Y : ndarray of complex, shape (n_f, n_y)
        The response to cancel (e.g. the DFT of a record without control).
    rhos : sequence of float
        Relative regularisations (-), each >= 0.

    Yields
    ------
    (rho, F) : float and ndarray of complex, shape (n_f, n_in)
        The inputs at each frequency (input unit, same scaling as ``Y``).
    """
    n_in = G.shape[2]
    AhA = np.einsum("fki,fkj->fij", G.conj(), G)
    AhY = np.einsum("fki,fk->fi", G.conj(), Y)
    scale = float(np.median(np.trace(AhA, axis1=1, axis2=2).real)) / n_in
    for rho in rhos:
        if rho == 0.0:
            F = -np.einsum("fij,fj->fi", np.linalg.pinv(G), Y)
        else:
            F = -np.linalg.solve(AhA + rho * scale * np.eye(n_in), AhY[..., None])[..., 0]
        yield float(rho), F


def least_squares_records(G, y, rhos, minimise=None, others=()):
    """Records under the periodic least-squares inputs, for each regularisation.

    The records ``y`` (e.g. without control) are taken as one period; on their DFT grid
    the inputs minimising the outputs ``minimise`` are :func:`least_squares_inputs`,
    and every output (and the ``others``) is recomputed with them.

    Parameters
    ----------
    G : ndarray of complex, shape (n // 2 + 1, n_y + n_o, n_in)
        The outputs of ``y`` then those of ``others`` per unit input, on the DFT grid
        ``numpy.fft.rfftfreq(n, dt)``.
    y : ndarray, shape (n_y, n)
        Records of the outputs, equally spaced.
    rhos : sequence of float
        Relative regularisations (:func:`least_squares_inputs`).
    minimise : sequence of int, optional
        Rows of ``y`` minimised; default all.
    others : ndarray, shape (n_o, n), optional
        Records of other outputs (e.g. constrained strokes), shown the same inputs.

    Yields
    ------
    (rho, y, others, inputs) : float and ndarray, shapes (n_y, n), (n_o, n), (n_in, n)
        The records with the inputs, and the inputs (input unit).
    """
    n = y.shape[1]
    ny = y.shape[0]
    if G.shape[0] != n // 2 + 1:
        raise ValueError(f"G has {G.shape[0]} frequencies; expected {n // 2 + 1}, the DFT "
                         f"grid of records of {n} samples (numpy.fft.rfftfreq(n, dt))")
    Gy, Go = G[:, :ny], G[:, ny:]
    Yd = np.fft.rfft(y, axis=1).T
    Od = np.fft.rfft(np.asarray(others), axis=1).T if len(others) else None
    sel = list(range(ny)) if minimise is None else list(minimise)
    for rho, F in least_squares_inputs(Gy[:, sel], Yd[:, sel], rhos):
        yy = np.fft.irfft((Yd + np.einsum("fki,fi->fk", Gy, F)).T, n, axis=1)
        oo = (None if Od is None
              else np.fft.irfft((Od + np.einsum("fki,fi->fk", Go, F)).T, n, axis=1))
        yield rho, yy, oo, np.fft.irfft(F.T, n, axis=1)


def record_ceiling(G, y, rhos, metric, others=(), fits=None) -> dict:
    """The least-squares ceiling of a record: exact cancellation, and the best within limits.

    With every output minimised and ``rho = rhos[0]`` (0: exact, minimum-norm inputs),
    and for each output alone over all ``rhos`` (:func:`least_squares_records`), the
    reduction of ``metric`` per output, the largest ``|others|`` and the largest
    ``|inputs|``; per output the regularisation whose row ``fits`` and reduces that
    output most.

    Parameters
    ----------
    G : ndarray of complex, shape (n // 2 + 1, n_y + n_o, n_in)
        As :func:`least_squares_records`.
    y : ndarray, shape (n_y, n)
        Records of the outputs, equally spaced.
    rhos : sequence of float
        Relative regularisations, the first used for the exact row (0 normally).
    metric : callable
        ``metric(record) -> float`` of one output's record, shape (n,) (e.g. a windowed
        peak-to-peak).
    others : ndarray, shape (n_o, n), optional
        Records of constrained outputs (e.g. strokes).
    fits : callable, optional
        ``fits(row) -> bool`` on a row (below); default every row fits.

    Returns
    -------
    dict
        ``"exact"``: the row of all outputs minimised at ``rhos[0]``; ``"best"``: per
        output its best fitting row, minimising it alone (None when none fits).  A row is
        a dict of ``rho``, ``reduction_pct`` (list per output, %), ``others_max`` and
        ``inputs_max`` (largest magnitudes, their units).
    """
    off = [float(metric(r)) for r in y]

    def rows(sel, rhos):
        return [{"rho": rho,
                 "reduction_pct": [100.0 * (1 - float(metric(r)) / o) for r, o in zip(yy, off)],
                 "others_max": None if oo is None else float(np.abs(oo).max()),
                 "inputs_max": float(np.abs(F).max())}
                for rho, yy, oo, F in least_squares_records(G, y, rhos, sel, others)]

    exact = rows(None, list(rhos)[:1])[0]
    best = []
    for i in range(len(y)):
        ok = [r for r in rows([i], rhos) if fits is None or fits(r)]
        best.append(max(ok, key=lambda r: r["reduction_pct"][i]) if ok else None)
    return {"exact": exact, "best": best}
