"""Control-system views of a :class:`~ctrlfmu.law.DiscreteLaw` (python-control).

Conversions to python-control systems, frequency responses, and the gain optimiser that
maximises the closed-loop damping of a target mode on a given plant.

Sign convention: the law's command is applied *as is*, ``u = K(z) y``, and a loop is
closed as ``y = G u``, i.e. with positive feedback.  A design that needs negative feedback
carries the minus sign in its own gains.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import control
import numpy as np
from scipy.optimize import minimize_scalar

from ctrlfmu.law import DimensionError, DiscreteLaw

__all__ = [
    "to_statespace",
    "frequency_response",
    "mode_damping",
    "GainResult",
    "closed_loop",
    "optimise_gain",
]


def to_statespace(law: DiscreteLaw, include_delay: bool = True) -> control.StateSpace:
    """Discrete python-control system of ``law`` (limits and activation ignored).

    Parameters
    ----------
    law : DiscreteLaw
        The control law.
    include_delay : bool, default True
        For the delayed form, add the one-sample output delay of Eq. (11) as ``n_out``
        extra states, so the system maps ``y`` to the command actually applied.  With
        False, or for the non-delayed form, the system is ``(A, B, C, D)``.

    Returns
    -------
    control.StateSpace
        Discrete system with ``dt = law.dt``, named inputs and outputs.
    """
    a, b, c, d = law.A, law.B, law.C, law.D
    if law.delayed and include_delay:
        n, m = law.n_states, law.n_outputs
        a = np.block([[a, np.zeros((n, m))], [c, np.zeros((m, m))]])
        b = np.vstack([b, d])
        c = np.hstack([np.zeros((m, n)), np.eye(m)])
        d = np.zeros_like(law.D)
    return control.ss(a, b, c, d, law.dt, inputs=list(law.inputs), outputs=list(law.outputs),
                      name=law.name)


def frequency_response(law: DiscreteLaw, f, include_delay: bool = True) -> np.ndarray:
    """Complex frequency response of ``law``.

    Parameters
    ----------
    law : DiscreteLaw
        The control law.
    f : array_like, shape (n_f,)
        Frequencies (Hz), below the Nyquist frequency ``1 / (2 dt)``.
    include_delay : bool, default True
        Include the one-sample delay of the delayed form (factor ``exp(-j 2 pi f dt)``).

    Returns
    -------
    ndarray, shape (n_out, n_in, n_f)
        ``H(exp(j 2 pi f dt))`` (V per input unit).
    """
    f = np.atleast_1d(np.asarray(f, dtype=float))
    z = np.exp(2j * np.pi * f * law.dt)
    n = law.n_states
    h = np.broadcast_to(law.D.astype(complex), (f.size, *law.D.shape)).copy()
    if n:
        resolvent = z[:, None, None] * np.eye(n) - law.A           # (n_f, n, n)
        h += law.C @ np.linalg.solve(resolvent, np.broadcast_to(law.B, (f.size, *law.B.shape)))
    if law.delayed and include_delay:
        h /= z[:, None, None]
    return np.moveaxis(h, 0, -1)


def mode_damping(poles, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequency and damping ratio of discrete poles.

    Parameters
    ----------
    poles : array_like, shape (n_p,)
        Poles in the z-plane (-).
    dt : float
        Sample period (s).

    Returns
    -------
    f_n : ndarray, shape (n_p,)
        Natural frequencies ``|s| / (2 pi)`` with ``s = log(z) / dt`` (Hz).
    zeta : ndarray, shape (n_p,)
        Damping ratios ``-Re(s) / |s|`` (-); poles at ``z = 0`` get ``zeta = 1``.
    """
    z = np.asarray(poles, dtype=complex)
    with np.errstate(divide="ignore"):
        s = np.log(z) / dt
    wn = np.abs(s)
    zeta = np.where(np.isfinite(wn) & (wn > 0), -s.real / np.where(wn > 0, wn, 1), 1.0)
    return np.where(np.isfinite(wn), wn, np.inf) / (2 * np.pi), zeta


def _discrete_plant(plant, dt: float) -> control.StateSpace:
    sys = control.ss(plant)
    if sys.ninputs != 1 or sys.noutputs != 1:
        raise DimensionError(
            f"plant has {sys.ninputs} input(s) and {sys.noutputs} output(s); expected a SISO plant"
        )
    if sys.isctime():
        # The DAC holds the command between samples: zero-order hold is exact.
        return control.sample_system(sys, dt, method="zoh")
    if sys.dt is not True and not math.isclose(sys.dt, dt, rel_tol=1e-9):
        raise ValueError(f"plant sample period {sys.dt} s differs from the law's {dt} s")
    return control.ss(sys.A, sys.B, sys.C, sys.D, dt)


def closed_loop(plant, law: DiscreteLaw) -> control.StateSpace:
    """Sampled closed loop of a SISO plant with ``law`` (positive feedback, ``u = K y``).

    Parameters
    ----------
    plant : control.StateSpace or control.TransferFunction
        SISO plant from command (V) to measurement; continuous plants are sampled with a
        zero-order hold at ``law.dt`` (exact for a held DAC output), discrete plants must
        have ``law.dt``.
    law : DiscreteLaw
        SISO law; its delay (delayed form) is included.

    Returns
    -------
    control.StateSpace
        Discrete closed loop from a disturbance added to ``u`` to the measurement.
    """
    if law.n_inputs != 1 or law.n_outputs != 1:
        raise DimensionError(
            f"law {law.name!r} has {law.n_inputs} input(s) and {law.n_outputs} output(s); "
            "expected a SISO law"
        )
    return control.feedback(_discrete_plant(plant, law.dt), to_statespace(law), sign=+1)


@dataclass(frozen=True)
class GainResult:
    """Result of :func:`optimise_gain`.

    Parameters
    ----------
    gain : float
        Best factor on the law's output (-).
    damping : float
        Worst damping ratio of the closed-loop poles near the mode at ``gain`` (-).
    open_loop_damping : float
        Same measure without control (-).
    law : DiscreteLaw
        ``law.with_gain(gain)``.
    poles : ndarray, shape (n_p,)
        Closed-loop z-plane poles near the mode (-).
    """

    gain: float
    damping: float
    open_loop_damping: float
    law: DiscreteLaw
    poles: np.ndarray


def optimise_gain(plant, law: DiscreteLaw, mode_hz: float, *, band=(0.5, 2.0),
                  gain_range=(1e-3, 1e2), n_grid: int = 121) -> GainResult:
    """Scale a SISO law to maximise the closed-loop damping of a target mode.

    The objective is the smallest damping ratio among the closed-loop poles whose natural
    frequency lies in ``band`` times ``mode_hz`` (the structural mode and, for a virtual
    absorber, the controller's own poles, which share the band); an unstable loop scores
    -1.  A log-spaced grid over ``gain_range`` is refined by a bounded scalar search.

    Parameters
    ----------
    plant : control.StateSpace or control.TransferFunction
        SISO plant from the law's command (V) to its measurement, continuous or discrete
        (see :func:`closed_loop`).
    law : DiscreteLaw
        SISO law whose output is scaled.
    mode_hz : float
        Target mode frequency (Hz).
    band : (float, float), default (0.5, 2.0)
        Frequency band around the mode, relative to ``mode_hz`` (-).
    gain_range : (float, float), default (1e-3, 1e2)
        Range of the factor on the law's output (-), positive.
    n_grid : int, default 121
        Grid points before refinement.

    Returns
    -------
    GainResult
        Best gain, damping ratio, open-loop damping and the scaled law.
    """
    if not (0 < gain_range[0] < gain_range[1]):
        raise ValueError(f"gain_range must be 0 < low < high, got {gain_range}")
    plant_d = _discrete_plant(plant, law.dt)
    lo, hi = band[0] * mode_hz, band[1] * mode_hz

    def near(poles):
        f_n, _ = mode_damping(poles, law.dt)
        return poles[(f_n >= lo) & (f_n <= hi)]

    def score(poles):
        if np.any(np.abs(poles) >= 1):
            return -1.0
        sel = near(poles)
        if sel.size == 0:
            return -1.0
        return float(np.min(mode_damping(sel, law.dt)[1]))

    ctrl = to_statespace(law)

    def cl_poles(g):
        return control.feedback(plant_d, g * ctrl, sign=+1).poles()

    ol = plant_d.poles()
    if near(ol).size == 0:
        raise ValueError(f"plant has no pole within {lo:.3g}-{hi:.3g} Hz of the {mode_hz} Hz mode")
    open_damping = float(np.min(mode_damping(near(ol), law.dt)[1]))
    logs = np.linspace(math.log10(gain_range[0]), math.log10(gain_range[1]), n_grid)
    scores = np.array([score(cl_poles(10 ** lg)) for lg in logs])
    i = int(np.argmax(scores))
    a, b = logs[max(i - 1, 0)], logs[min(i + 1, n_grid - 1)]
    res = minimize_scalar(lambda lg: -score(cl_poles(10 ** lg)), bounds=(a, b),
                          method="bounded", options={"xatol": 1e-6})
    best_lg, best = (res.x, -res.fun) if -res.fun >= scores[i] else (logs[i], scores[i])
    gain = float(10 ** best_lg)
    poles = cl_poles(gain)
    return GainResult(gain, float(best), open_damping, law.with_gain(gain), near(poles))
