"""Bouc–Wen hysteresis between applied voltage and free stroke (pure numerics, SI).

The free stroke of a hysteretic stack is ``d0 / V0 * (v - h)`` with the Bouc–Wen state ``h``
(V) driven by the applied voltage ``v`` (exponent ``n = 1``, the form commonly identified for
piezo stacks):

    dh/dt = alpha dv/dt - beta |dv/dt| h - gamma dv/dt |h|

Dividing by ``dv/dt`` shows that ``h`` depends on the voltage *path* only, not on its timing
(rate independence).  Along a monotone voltage increment, and while ``h`` keeps its sign,
the equation is linear in ``h`` and is integrated exactly:

    s = sign(dv),  sigma = sign(h),  k = beta + s sigma gamma,  h_inf = s alpha / k
    h(|dv|) = h_inf + (h0 - h_inf) exp(-k |dv|)

with a split where ``h`` crosses zero.  Hence applying a path in pieces gives the same
``h`` as applying it at once (to round-off), whatever the pieces.  ``beta > |gamma|`` keeps
``k > 0`` so that ``h`` stays bounded by ``alpha / (beta - gamma)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["BoucWen", "HysteresisError", "increment", "step"]


class HysteresisError(ValueError):
    """Invalid hysteresis parameters."""


@dataclass(frozen=True)
class BoucWen:
    """Bouc–Wen hysteresis parameters (exponent ``n = 1``).

    Parameters
    ----------
    alpha : float
        Gain of ``dh/dv`` at ``h = 0`` (-), ``alpha > 0``.
    beta : float
        Shape parameter (1/V), ``beta > |gamma|``.
    gamma : float
        Shape parameter (1/V).
    """

    alpha: float
    beta: float
    gamma: float

    def __post_init__(self):
        if not (self.alpha > 0 and math.isfinite(self.alpha)):
            raise HysteresisError(f"Bouc-Wen alpha must be positive and finite, got {self.alpha!r}")
        if not (math.isfinite(self.beta) and math.isfinite(self.gamma)
                and self.beta > abs(self.gamma)):
            raise HysteresisError(
                f"Bouc-Wen parameters need beta > |gamma|, got beta={self.beta!r}, "
                f"gamma={self.gamma!r}"
            )

    @classmethod
    def scaled(cls, alpha: float, beta_v0: float, gamma_v0: float, v0: float) -> "BoucWen":
        """Build from dimensionless ``beta V0`` and ``gamma V0`` for a voltage scale ``V0`` (V).

        Parameters
        ----------
        alpha : float
            Gain of ``dh/dv`` at ``h = 0`` (-).
        beta_v0, gamma_v0 : float
            Shape parameters times ``V0`` (-).
        v0 : float
            Voltage scale ``V0`` (V), e.g. the stack's rated voltage.

        Returns
        -------
        BoucWen
            With ``beta = beta_v0 / v0`` and ``gamma = gamma_v0 / v0`` (1/V).
        """
        return cls(alpha, beta_v0 / v0, gamma_v0 / v0)

    @property
    def h_max(self) -> float:
        """Asymptotic ``|h|`` under a long monotone sweep, ``alpha / (beta + gamma)`` (V)."""
        return self.alpha / (self.beta + self.gamma)

    def replace(self, **changes) -> "BoucWen":
        """Copy with some fields changed."""
        return replace(self, **changes)


def _segment(bw: BoucWen, h: float, s: float, w: float, sigma: float) -> float:
    k = bw.beta + s * sigma * bw.gamma
    h_inf = s * bw.alpha / k
    return h_inf + (h - h_inf) * math.exp(-k * w)


def increment(bw: BoucWen, h: float, dv: float) -> float:
    """Advance the Bouc–Wen state over a monotone voltage increment, exactly.

    Parameters
    ----------
    bw : BoucWen
        Parameters.
    h : float
        State before the increment (V).
    dv : float
        Voltage increment (V).

    Returns
    -------
    float
        State after the increment (V).
    """
    if dv == 0.0:
        return h
    s = 1.0 if dv > 0 else -1.0
    w = abs(dv)
    if h * s < 0.0:
        # h moves from the sign opposite to s toward h_inf (sign s): it may cross zero.
        sigma = -s
        k = bw.beta + s * sigma * bw.gamma
        h_inf = s * bw.alpha / k
        w0 = math.log1p(-h / h_inf) / k
        if w0 >= w:
            return _segment(bw, h, s, w, sigma)
        h, w = 0.0, w - w0
    return _segment(bw, h, s, w, s)


def step(bw: BoucWen, h: float, v_start: float, v_path) -> float:
    """Advance the Bouc–Wen state along a piecewise-linear voltage path.

    Parameters
    ----------
    bw : BoucWen
        Parameters.
    h : float
        State at the start (V).
    v_start : float
        Voltage at the start (V).
    v_path : array_like, shape (n,)
        Voltages visited in order (V); linear between points, so each piece is monotone.

    Returns
    -------
    float
        State at the end of the path (V).
    """
    v_prev = float(v_start)
    for v in np.asarray(v_path, dtype=float).tolist():
        h = increment(bw, h, v - v_prev)
        v_prev = v
    return h
