"""One verdict per paper target: the paper's words, its number, ours, and the band between.

The paper's targets come in a few kinds of words, each read one way, stated here once:

* ``"about X"`` -- within ``ABOUT`` of X, in X's own unit (``ABOUT_PCT`` = 5 points for a
  percentage: "about 80 %" is 75-85 %, "about 30 %" 25-35 %; ``ABOUT_HZ`` = 5 Hz for a
  frequency);
* ``"X-Y"`` -- from X to Y, both included;
* ``"at least X"`` ("significant" is read as at least 50 %), ``"below X"``.

A verdict is ``reproduced`` only inside its own band; the experiments' ``reproduced`` is
true only when every verdict is.  Outside its band a verdict says on which side: each
target knows which way is better for the spacecraft (``better``: a larger reduction or
isolation bandwidth, a smaller stroke or decay), so its ``outcome`` is ``"reproduced"``,
``"beats the paper"`` (outside the band on the better side: a variant that removes more
than the paper reports), ``"missed"`` (on the worse side) or ``"not measured"``; a target
with no better side is ``"missed"`` either way.  :func:`overall` is the one line an
experiment states: reproduced, reproduced or beaten on every target, or what it missed.
"""

from __future__ import annotations

import math

__all__ = ["ABOUT_PCT", "ABOUT_HZ", "about", "between", "at_least", "below", "all_reproduced",
           "REPRODUCED", "BEATS", "MISSED", "NOT_MEASURED", "outcome_words", "overall",
           "inconsistencies"]

#: Half-width of "about X %" (percentage points).
ABOUT_PCT = 5.0
#: Half-width of "about X Hz" (Hz).
ABOUT_HZ = 5.0


#: The four outcomes of a verdict.
REPRODUCED, BEATS, MISSED, NOT_MEASURED = ("reproduced", "beats the paper", "missed",
                                           "not measured")


def _outcome(lo, hi, ours, better):
    if ours is None or not math.isfinite(ours):
        return NOT_MEASURED
    if lo <= ours <= hi:
        return REPRODUCED
    above = ours > hi
    if better == "higher":
        return BEATS if above else MISSED
    if better == "lower":
        return MISSED if above else BEATS
    return MISSED


def _verdict(target, words, band, ours, unit, better=None):
    if better not in (None, "higher", "lower"):
        raise ValueError(f"better={better!r}: use 'higher', 'lower' or None")
    lo, hi = band
    outcome = _outcome(lo, hi, ours, better)
    # an open end is None in the JSON (no Infinity there)
    return {"target": target, "paper": words,
            "band": [lo if math.isfinite(lo) else None, hi if math.isfinite(hi) else None],
            "ours": ours, "unit": unit, "reproduced": outcome == REPRODUCED,
            "better": better, "outcome": outcome}


def about(target: str, x: float, ours, unit: str = "%", better: str | None = None) -> dict:
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
    better : {"higher", "lower"}, optional
        Which side of the band is better for the spacecraft (a reduction: higher); None
        when neither is.

    Returns
    -------
    dict
        ``target``, ``paper`` (its words), ``band``, ``ours``, ``unit``, ``reproduced``,
        ``better`` and ``outcome`` (one of ``REPRODUCED``, ``BEATS``, ``MISSED``,
        ``NOT_MEASURED``).
    """
    half = ABOUT_HZ if unit == "Hz" else ABOUT_PCT
    return _verdict(target, f"about {x:g} {unit}", (x - half, x + half), ours, unit, better)


def between(target: str, lo: float, hi: float, ours, unit: str = "%",
            better: str | None = None) -> dict:
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
    better : {"higher", "lower"}, optional
        Which side of the range is better; see :func:`about`.

    Returns
    -------
    dict
        As :func:`about`.
    """
    return _verdict(target, f"{lo:g}-{hi:g} {unit}", (lo, hi), ours, unit, better)


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
    return _verdict(target, words or f"at least {x:g} {unit}", (x, math.inf), ours, unit,
                    "higher")


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
                    unit, "lower")


def all_reproduced(verdicts) -> bool:
    """True only when every verdict is.

    Parameters
    ----------
    verdicts : sequence of dict
        Verdicts of :func:`about`, :func:`between`, :func:`at_least`, :func:`below`.
    """
    return all(v["reproduced"] for v in verdicts)


def outcome_words(v: dict, digits: int = 1) -> str:
    """One verdict as words: ``"<target>: 59.4 % (paper about 30 %, beats the paper)"``.

    Parameters
    ----------
    v : dict
        A verdict of :func:`about`, :func:`between`, :func:`at_least` or :func:`below`.
    digits : int
        Decimals of ``ours``.
    """
    ours = v["ours"]
    num = "not measured" if ours is None else f"{ours:.{digits}f} {v['unit']}".strip()
    return f"{v['target']}: {num} (paper {v['paper']}, {v['outcome']})"


def overall(verdicts) -> str:
    """The experiment's verdict in one line.

    ``"reproduced"`` when every target is inside its band; ``"reproduced or beaten on
    every target (beats the paper on: ...)"`` when none is missed; otherwise ``"missed:
    ..."`` naming the missed targets, followed by the beaten ones.

    Parameters
    ----------
    verdicts : sequence of dict
        Verdicts of :func:`about`, :func:`between`, :func:`at_least`, :func:`below`.
    """
    beaten = [v["target"] for v in verdicts if v["outcome"] == BEATS]
    missed = [v["target"] for v in verdicts if v["outcome"] in (MISSED, NOT_MEASURED)]
    if not beaten and not missed:
        return REPRODUCED
    if not missed:
        return "reproduced or beaten on every target (beats the paper on: " + \
            "; ".join(beaten) + ")"
    return ("missed: " + "; ".join(missed)
            + (" (beats the paper on: " + "; ".join(beaten) + ")" if beaten else ""))


def inconsistencies(result: dict) -> list:
    """What an experiment's JSON claims that its own numbers do not say (empty: nothing).

    Every verdict marked ``reproduced`` must have ``ours`` inside its ``band`` (an open
    end is None), every verdict whose ``ours`` is inside its band must be marked so, and
    the experiment's ``reproduced`` must be true exactly when every verdict is.

    Parameters
    ----------
    result : dict
        An experiment's result, as written to ``NAME.json`` (``verdicts`` and
        ``reproduced``; an experiment without verdicts has nothing to check).

    Returns
    -------
    list of str
        One sentence per inconsistency.
    """
    out = []
    verdicts = result.get("verdicts") or []
    for v in verdicts:
        lo, hi = v["band"]
        ours = v["ours"]
        inside = (ours is not None and math.isfinite(ours)
                  and (lo is None or ours >= lo) and (hi is None or ours <= hi))
        if bool(v["reproduced"]) != inside:
            out.append(f"{v['target']}: ours {ours} is {'inside' if inside else 'outside'} "
                       f"the band {v['band']} but reproduced is {v['reproduced']}")
    if verdicts and "reproduced" in result and \
            bool(result["reproduced"]) != all(v["reproduced"] for v in verdicts):
        out.append(f"the experiment's reproduced is {result['reproduced']} but its verdicts "
                   f"say {all(v['reproduced'] for v in verdicts)}")
    return out
