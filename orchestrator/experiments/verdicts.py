"""One verdict per paper target: the paper's words, its number, ours, and the band between.

The paper's targets come in a few kinds of words, each read one way, stated here once:

* ``"about X"`` -- within ``ABOUT`` of X, in X's own unit (``ABOUT_PCT`` = 5 points for a
  percentage: "about 80 %" is 75-85 %, "about 30 %" 25-35 %; ``ABOUT_HZ`` = 5 Hz for a
  frequency);
* ``"X-Y"`` -- from X to Y, both included;
* ``"at least X"`` ("significant" is read as at least 50 %), ``"below X"``.

A verdict is ``reproduced`` only inside its own band; the experiments' ``reproduced`` is
true only when every verdict is.
"""

from __future__ import annotations

import math

__all__ = ["ABOUT_PCT", "ABOUT_HZ", "about", "between", "at_least", "below", "all_reproduced"]

#: Half-width of "about X %" (percentage points).
ABOUT_PCT = 5.0
#: Half-width of "about X Hz" (Hz).
ABOUT_HZ = 5.0


def _verdict(target, words, band, ours, unit):
    lo, hi = band
    ok = ours is not None and math.isfinite(ours) and lo <= ours <= hi
    # an open end is None in the JSON (no Infinity there)
    return {"target": target, "paper": words,
            "band": [lo if math.isfinite(lo) else None, hi if math.isfinite(hi) else None],
            "ours": ours, "unit": unit, "reproduced": bool(ok)}


def about(target: str, x: float, ours, unit: str = "%") -> dict:
    """Verdict on "about ``x``" (``x`` +- ``ABOUT_PCT`` or ``ABOUT_HZ``).

    Parameters
    ----------
    target : str
        What is compared, in the paper's terms (e.g. "Fig. 15: mount #3 alone").
    x : float
        The paper's number.
    ours : float or None
        Ours (None: not measured, never reproduced).
    unit : {"%", "Hz"}

    Returns
    -------
    dict
        ``target``, ``paper`` (its words), ``band``, ``ours``, ``unit``, ``reproduced``.
    """
    half = ABOUT_HZ if unit == "Hz" else ABOUT_PCT
    return _verdict(target, f"about {x:g} {unit}", (x - half, x + half), ours, unit)


def between(target: str, lo: float, hi: float, ours, unit: str = "%") -> dict:
    """Verdict on "``lo``-``hi``" (both included); see :func:`about`.

    Parameters
    ----------
    target : str
        What is compared, in the paper's terms.
    lo, hi : float
        The paper's range.
    ours : float or None
        Ours (None: not measured, never reproduced).
    unit : str
        Unit of the numbers.

    Returns
    -------
    dict
        As :func:`about`.
    """
    return _verdict(target, f"{lo:g}-{hi:g} {unit}", (lo, hi), ours, unit)


def at_least(target: str, x: float, ours, unit: str = "%", words: str | None = None) -> dict:
    """Verdict on "at least ``x``" (``words`` are the paper's, e.g. "significant").

    Parameters
    ----------
    target : str
        What is compared, in the paper's terms.
    x : float
        The paper's bound.
    ours : float or None
        Ours (None: not measured, never reproduced).
    unit : str
        Unit of the numbers.
    words : str, optional
        The paper's words, when they are not a number.

    Returns
    -------
    dict
        As :func:`about`.
    """
    return _verdict(target, words or f"at least {x:g} {unit}", (x, math.inf), ours, unit)


def below(target: str, x: float, ours, unit: str = "", words: str | None = None) -> dict:
    """Verdict on "below ``x``" (``x`` included as the limit: ``ours <= x``).

    Parameters
    ----------
    target : str
        What is compared, in the paper's terms.
    x : float
        The paper's limit.
    ours : float or None
        Ours (None: not measured, never reproduced).
    unit : str
        Unit of the numbers.
    words : str, optional
        The paper's words, when they are not a number.

    Returns
    -------
    dict
        As :func:`about`.
    """
    return _verdict(target, words or f"below {x:g} {unit}".strip(), (-math.inf, x), ours,
                    unit)


def all_reproduced(verdicts) -> bool:
    """True only when every verdict is."""
    return all(v["reproduced"] for v in verdicts)
