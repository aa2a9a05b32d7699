"""Communication points robust to the host's time arithmetic.

Hosts pass a step's start time ``t`` and size ``h`` in different ways: the exact tick
time and the exact period (so ``t + h`` may miss the next tick by an ulp), an accumulated
``t += h``, or ``(k + 1) h - k h``.  A source evaluated at ``t + h`` then sees a
discontinuity (a slew's phase change, a window edge, a chopper flank) one step early or
late, depending on the host.  :func:`end_time` maps every such variant of one time to one
float.
"""

from __future__ import annotations

__all__ = ["end_time"]

# picoseconds are counted exactly in a double below 2**53 ps (about 9007 s)
_PS = 1e12
_LIMIT = 9.0e3
# within rounding: a few ulps of the sum
_ULPS = 4 * 2.220446049250313e-16


def end_time(t: float, h: float, last: float | None = None) -> float:
    """The communication point ``t + h``, on the picosecond grid when within rounding.

    Parameters
    ----------
    t : float
        Start of the step (s), as the host passes it.
    h : float
        Step size (s).
    last : float, optional
        The end of the previous step as this function returned it: when ``t`` is
        within ``1e-6 h`` of it (a host that accumulates ``t += h`` drifts by ulps per
        step), the step starts there instead, so the drift never accumulates.

    Returns
    -------
    float
        The multiple of 1 ps nearest ``t + h``, correctly rounded (``k / 1000`` for the
        tick ``k`` of a 1 ms step), when it lies within 4 ulps of it; else ``t + h``.
        The same rule as ``jf_end_time`` of the native FMUs.
    """
    if last is not None and abs(t - last) <= 1e-6 * abs(h):
        t = last
    te = t + h
    if not abs(te) < _LIMIT:
        return te
    g = _nearbyint(te * _PS) / _PS
    return g if abs(g - te) <= _ULPS * abs(te) else te


def _nearbyint(x: float) -> float:
    """Round half to even, as C99 ``nearbyint`` in the default rounding mode."""
    return float(round(x))
