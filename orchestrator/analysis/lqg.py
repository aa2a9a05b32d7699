"""One controller for many piezo stacks: an LQG on their sensors, in Eq. (11) form.

Where each stack feeding back its own sensor (:func:`~orchestrator.analysis.sampled.
stack_loop` with one SISO law per channel) cannot reach a performance output, one law
on all the sensors may.  :func:`stack_lqg` designs it on a sampled structure with the
stack amplifiers' lag (:func:`~orchestrator.analysis.sampled.amplifier_step`), and
:func:`lqg_law` packs it as the :class:`ctrlfmu.law.DiscreteLaw` a controller FMU runs:
its command is applied one sample after the measurement it used, as in the
co-simulation.  python-control is imported where it is used.
"""

from __future__ import annotations

import numpy as np

__all__ = ["stack_lqg", "lqg_law"]


def stack_lqg(A, Bf, Cs, Cp, bw, *, amplifier: tuple, rho: float, q: float,
              snr: float) -> dict:
    """LQG gains for stack forces driven through their amplifiers, sensors read.

    * performance: the outputs ``Cp``, control weight ``rho`` times the squared largest
      static gain from a stack force to them;
    * Kalman filter: process noise along the disturbance direction ``bw``, plus ``q``
      times its sensor-equivalent at the stack forces (input-noise robustness, which
      buys gain margin), sensor noise ``snr`` times the disturbance's largest static
      sensor signal.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Sampled structure without its rigid-body states (they must not be in the design
        model: the stack forces cannot move them).
    Bf : ndarray, shape (n, m)
        Stack force inputs (N).
    Cs : ndarray, shape (m_s, n)
        Sensor outputs (e.g. stack strains, -).
    Cp : ndarray, shape (p, n)
        Performance outputs (e.g. a line-of-sight angle, rad).
    bw : ndarray, shape (n,)
        The disturbance's input direction (per unit of its dominant component).
    amplifier : (a, cx, cu)
        The amplifier over one step (:func:`~orchestrator.analysis.sampled.
        amplifier_step`).
    rho, q, snr : float
        Weights (dimensionless), see above.

    Returns
    -------
    dict
        ``Aa``, ``Ba``, ``Ca``: the design model, state ``[x, p]`` with ``p`` the
        amplifiers' force, ``u`` the commanded force (N): ``p+ = a p + (1 - a) u``, the
        structure holds ``cx p + cu u``; ``K`` (state feedback, ``u = -K xh``) and ``L``
        (one-step predictor gain).
    """
    # deferred: python-control takes about 1 s to load
    import control

    n, m, ms = A.shape[0], Bf.shape[1], Cs.shape[0]
    static = np.linalg.solve(np.eye(n) - A, np.column_stack([Bf, bw]))
    a, cx, cu = amplifier
    Aa = np.block([[A, cx * Bf], [np.zeros((m, n)), a * np.eye(m)]])
    Ba = np.vstack([cu * Bf, (1.0 - a) * np.eye(m)])
    Ca = np.hstack([Cs, np.zeros((ms, m))])
    Cpa = np.hstack([Cp, np.zeros((Cp.shape[0], m))])
    R = rho * np.abs(Cp @ static[:, :m]).max() ** 2 * np.eye(m)
    K = control.dlqr(Aa, Ba, Cpa.T @ Cpa, R)[0]
    strain_w, strain_f = np.abs(Cs @ static[:, m]).max(), np.abs(Cs @ static[:, :m]).max()
    Gw = np.vstack([np.column_stack([bw, q * strain_w / strain_f * Bf]),
                    np.zeros((m, 1 + m))])
    V = (snr * strain_w) ** 2 * np.eye(ms)
    # dlqe's gain is the one-step predictor's, A P C' (C P C' + V)^-1
    L = control.dlqe(Aa, Gw, Ca, np.eye(1 + m), V)[0]
    return {"Aa": Aa, "Ba": Ba, "Ca": Ca, "K": K, "L": L}


def lqg_law(gains: dict, n_channels: int, sensors, actuators, *, force_per_volt: float,
            u_max: float, dt: float, **names):
    """The LQG of :func:`stack_lqg` as a delayed discrete law (Eq. 11).

    The predictor ``xh_{k+1} = (Aa - Ba K - L Ca) xh_k + L y_k`` with the command
    ``u_k = -K xh_k``; in Eq. (11) form the output at ``t_{k+1}`` is
    ``-K xh_{k+1} = -K Ac xh_k - K L y_k``, in volts (``u / force_per_volt``).

    Parameters
    ----------
    gains : dict
        :func:`stack_lqg`'s result.
    n_channels : int
        Inputs and outputs of the law (all channels, read or not).
    sensors, actuators : sequence of int
        The channels whose sensors it reads and whose stacks it drives (the others get
        zero columns and rows), in the order of ``Ca``'s rows and ``Ba``'s inputs.
    force_per_volt : float
        Stack blocked force per volt ``c h`` (N/V).
    u_max : float
        Command limit, both signs (V).
    dt : float
        Sample period (s).
    **names
        ``name``, ``inputs``, ``outputs``, ``input_units``, ``output_units``,
        ``description`` of the :class:`ctrlfmu.law.DiscreteLaw`.

    Returns
    -------
    ctrlfmu.law.DiscreteLaw
    """
    from ctrlfmu.law import DiscreteLaw

    Aa, Ba, Ca, K, L = (gains[k] for k in ("Aa", "Ba", "Ca", "K", "L"))
    Ac = Aa - Ba @ K - L @ Ca
    nl = n_channels
    B, C, D = (np.zeros(shape) for shape in ((len(Ac), nl), (nl, len(Ac)), (nl, nl)))
    B[:, sensors] = L
    C[actuators] = -K @ Ac / force_per_volt
    D[np.ix_(actuators, sensors)] = -K @ L / force_per_volt
    return DiscreteLaw(Ac, B, C, D, dt, delayed=True, u_min=-u_max, u_max=u_max, **names)
