"""Exact co-simulation time: rational periods, a base step and integer ticks.

Every period is an exact :class:`fractions.Fraction`.  The base step is the GCD of all
periods and the output interval; time is ``tick * base`` evaluated from the exact rational
(never accumulated), and a precomputed pattern over one hyperperiod says which instances
are due at each tick.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from numbers import Rational

__all__ = ["TimebaseError", "Timebase", "to_fraction", "make_timebase"]

#: Smallest base step accepted (s); a smaller one means the periods share no sane base.
MIN_BASE = Fraction(1, 10**12)
#: Largest number of base ticks in one run.
MAX_TICKS = 10**9
#: Largest denominator tried when recovering a simple rational from a float.
_MAX_DENOMINATOR = 10**6


class TimebaseError(ValueError):
    """Periods, intervals or times that have no exact common base step."""


def to_fraction(value, what: str = "time") -> Fraction:
    """Convert a time given as int, Fraction, decimal string or float to a Fraction.

    A float is read through its shortest decimal representation, so ``1e-3`` becomes
    exactly 1/1000.  When a simpler rational (denominator up to 10**6) rounds to the very
    same float, that one is used, so ``1/3`` written as a float becomes exactly 1/3.

    Parameters
    ----------
    value : int, float, str or Fraction
        The time or period (s).
    what : str
        Name used in error messages.

    Returns
    -------
    Fraction
        The exact value (s).
    """
    if isinstance(value, bool):
        raise TimebaseError(f"{what} must be a number; got the boolean {value!r}")
    if isinstance(value, Rational):
        return Fraction(value)
    if isinstance(value, str):
        try:
            return Fraction(value.strip())
        except (ValueError, ZeroDivisionError):
            raise TimebaseError(f"{what} {value!r} is not a number") from None
    if isinstance(value, float):
        if not math.isfinite(value):
            raise TimebaseError(f"{what} must be finite; got {value!r}")
        exact = Fraction(repr(value))
        simple = exact.limit_denominator(_MAX_DENOMINATOR)
        if simple != exact and float(simple) == value:
            return simple
        return exact
    raise TimebaseError(f"{what} must be a number; got {type(value).__name__} {value!r}")


def _gcd(a: Fraction, b: Fraction) -> Fraction:
    return Fraction(math.gcd(a.numerator, b.numerator), math.lcm(a.denominator, b.denominator))


@dataclass(frozen=True)
class Timebase:
    """The exact tick grid of one run.

    Attributes
    ----------
    base : Fraction
        Base step (s), the GCD of all periods and the output interval.
    start : Fraction
        Start time (s); a multiple of `base` is not required.
    n_ticks : int
        Number of base steps from start to stop.
    period_ticks : dict of str to int
        Communication period of each instance, in base ticks.
    output_ticks : int
        Output interval in base ticks.
    hyperperiod : int
        Least common multiple of all period ticks and the output ticks.
    """

    base: Fraction
    start: Fraction
    n_ticks: int
    period_ticks: dict
    output_ticks: int
    hyperperiod: int

    def time(self, tick: int) -> float:
        """Return the communication point of `tick` as the nearest float (s)."""
        num = (self.start + tick * self.base)
        return num.numerator / num.denominator

    def times(self, ticks) -> list:
        """Return the float times of an iterable of ticks (s), as :meth:`time` does."""
        t0 = self.start + 0 * self.base
        d = t0.denominator * self.base.denominator
        a = t0.numerator * self.base.denominator
        b = self.base.numerator * t0.denominator
        return [(a + k * b) / d for k in ticks]   # int true division: correctly rounded

    def ticks_of(self, t, what: str = "time") -> int:
        """Return the tick of an exact time on the grid, or raise TimebaseError.

        Parameters
        ----------
        t : int, float, str or Fraction
            Time (s), read by :func:`to_fraction`.
        what : str
            Name of the time in error messages.

        Returns
        -------
        int
            Tick ``k`` with ``t = start + k base``.
        """
        q = (to_fraction(t, what) - self.start) / self.base
        if q.denominator != 1:
            raise TimebaseError(
                f"{what} {float(to_fraction(t, what))!r} s is not on the base grid of "
                f"{_fmt(self.base)} s starting at {float(self.start)!r} s"
            )
        return int(q)

    def due_pattern(self, names) -> list:
        """Return, for each tick of one hyperperiod, the tuple of names that step then."""
        return [
            tuple(n for n in names if k % self.period_ticks[n] == 0)
            for k in range(self.hyperperiod)
        ]


def _fmt(x: Fraction) -> str:
    return f"{float(x):.9g}" if x.denominator != 1 else str(x.numerator)


def make_timebase(periods: dict, output_interval, stop, start=0) -> Timebase:
    """Build the exact tick grid for instance periods, output interval and stop time.

    Parameters
    ----------
    periods : dict of str to number
        Communication period of each instance (s), each > 0.
    output_interval : number
        Interval between recorded rows (s), > 0.
    stop : number
        Stop time (s), > start and on the base grid.
    start : number
        Start time (s).

    Returns
    -------
    Timebase
    """
    fr = {name: to_fraction(p, f"period of instance {name!r}") for name, p in periods.items()}
    for name, p in fr.items():
        if p <= 0:
            raise TimebaseError(f"period of instance {name!r} is {float(p)!r} s; expected > 0")
    out = to_fraction(output_interval, "output interval")
    if out <= 0:
        raise TimebaseError(f"output interval is {float(out)!r} s; expected > 0")
    t0 = to_fraction(start, "start time")
    t1 = to_fraction(stop, "stop time")
    if t1 <= t0:
        raise TimebaseError(f"stop time {float(t1)!r} s is not after start time {float(t0)!r} s")
    base = out
    for p in fr.values():
        base = _gcd(base, p)
    if base < MIN_BASE:
        raise TimebaseError(
            f"the periods {sorted(float(p) for p in fr.values())} and output interval "
            f"{float(out)!r} s share no base step above 1e-12 s (GCD {base}); give periods "
            "that are multiples of a common step"
        )
    span = (t1 - t0) / base
    if span.denominator != 1:
        raise TimebaseError(
            f"run length {float(t1 - t0)!r} s is not a multiple of the base step "
            f"{_fmt(base)} s; choose a stop time on that grid"
        )
    n_ticks = int(span)
    if n_ticks > MAX_TICKS:
        raise TimebaseError(
            f"the run needs {n_ticks} base steps of {_fmt(base)} s; at most {MAX_TICKS} "
            "are allowed (use periods with a larger common step)"
        )
    period_ticks = {name: int(p / base) for name, p in fr.items()}
    output_ticks = int(out / base)
    hyper = output_ticks
    for k in period_ticks.values():
        hyper = math.lcm(hyper, k)
    return Timebase(base, t0, n_ticks, period_ticks, output_ticks, hyper)
