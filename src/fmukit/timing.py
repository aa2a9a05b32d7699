"""Communication points robust to the host's time arithmetic.

Hosts pass a step's start time ``t`` and size ``h`` in different ways: the exact tick
time and the exact period (so ``t + h`` may miss the next tick by an ulp), an accumulated
``t += h``, or ``(k + 1) h - k h``.  A source evaluated at ``t + h`` then sees a
discontinuity (a slew's phase change, a window edge, a chopper flank) one step early or
late, depending on the host.  :func:`end_time` maps every such variant of one time to one
float; :func:`reached` compares a time with an event within a fraction of the step (a
host whose clock drifts by 1e-12 s must not move a burst's end by a step);
:func:`same_step` says when a step size is a known one up to the host's rounding (a
discretisation made for it is reused).
"""

from __future__ import annotations

import sys

__all__ = ["STEP_RTOL", "TIME_RTOL", "end_time", "reached", "same_step"]

# picoseconds are counted exactly in a double below 2**53 ps (about 9007 s)
_PS = 1e12
# the grid a drifting host's time is brought back to: periods of the suite are whole
# microseconds (1 ms, 4 ms, 0.25 ms, 0.1 s)
_US = 1e6
_LIMIT = 9.0e3
# within rounding: a few ulps of the sum
_ULPS = 4 * 2.220446049250313e-16
#: Two times closer than this fraction of a step (or sample period) are one time.
TIME_RTOL = 1e-6
#: A step within this relative difference of a known step is that step (host rounding:
#: ``(k + 1) h - k h`` differs from ``h`` by up to ``ulp(t)``, 5.5e-13 of 1 ms at 8 s).
STEP_RTOL = 1e-9


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
        within ``TIME_RTOL h`` of it (a host that accumulates ``t += h`` drifts by ulps
        per step), the step starts there instead, so the drift never accumulates.

    Returns
    -------
    float
        The multiple of 1 ps nearest ``t + h``, correctly rounded (``k / 1000`` for the
        tick ``k`` of a 1 ms step), when it lies within 4 ulps of it; else the multiple
        of 1 µs nearest it when within ``TIME_RTOL h`` (a host whose clock drifts by
        1e-12 s still meets a source's edges on its samples); else ``t + h``.  The
        same rule as ``jf_end_time`` of the native FMUs.
    """
    if last is not None and abs(t - last) <= TIME_RTOL * abs(h):
        t = last
    te = t + h
    if not abs(te) < _LIMIT:
        return te
    g = _nearbyint(te * _PS) / _PS
    if abs(g - te) <= _ULPS * abs(te):
        return g
    # a host whose clock drifts (or whose steps are off by more than rounding): a time
    # within TIME_RTOL of a step of a whole microsecond is that microsecond
    g = _nearbyint(te * _US) / _US
    return g if abs(g - te) <= TIME_RTOL * abs(h) else te


def reached(t: float, event: float, period: float) -> bool:
    """Whether time ``t`` is at or after ``event``, within ``TIME_RTOL`` of ``period``.

    Parameters
    ----------
    t : float
        Time (s), e.g. a communication point.
    event : float
        Time of the event (s), e.g. the end of a burst.
    period : float
        Step or sample period (s) that sets the tolerance; 0 for an exact comparison.

    Returns
    -------
    bool
        ``t >= event - TIME_RTOL * period``.  The same rule as ``jf_reached``.
    """
    return t >= event - TIME_RTOL * abs(period)


def same_step(h: float, known: float, t: float = 0.0) -> bool:
    """Whether step ``h`` is the step ``known`` up to the host's rounding.

    Parameters
    ----------
    h : float
        Step size the host passes (s).
    known : float
        A step size already met or declared (s).
    t : float
        Time the step ends at (s): a host that accumulates ``t += h`` and shortens its
        last step to land on its stop time is off by a few ulps of ``t`` per step taken
        (fmuCheck's last step at ``-s 12``: 1.0e-12 s short of 1 ms).  0: no steps taken.

    Returns
    -------
    bool
        ``|h - known| <= max(STEP_RTOL |known|, 4 eps |t| (1 + |t| / |known|))``, never
        more than a quarter of ``known``.  The same rule as ``jf_same_step``.
    """
    k = abs(known)
    tol = max(STEP_RTOL * k, 4.0 * sys.float_info.epsilon * abs(t) * (1.0 + abs(t) / k))
    return abs(h - known) <= min(tol, 0.25 * k)


def _nearbyint(x: float) -> float:
    """Round half to even, as C99 ``nearbyint`` in the default rounding mode."""
    return float(round(x))
