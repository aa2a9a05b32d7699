"""The one progress bar of the project (tqdm), for runs and for campaigns.

A run reports the fraction of its simulated time; a campaign counts its cases and the
failed ones.  The bar is drawn on stderr only when stderr is a terminal (unless forced),
appears after ``delay`` seconds, and is erased when closed.
"""

from __future__ import annotations

import sys

from tqdm import tqdm


class ProgressBar:
    """A progress bar over ``total`` units, drawn on a terminal only.

    Parameters
    ----------
    total : float
        Units at the end (1.0 for a fraction of a run; the number of cases).
    label : str
        Text before the bar.
    unit : str
        Name of one unit (``"case"``); empty for a fraction.
    enabled : bool, optional
        Force on or off; default: on when ``stream`` is a terminal.
    delay : float
        Seconds before the bar first appears (s).
    stream : file, optional
        Default ``sys.stderr``.
    """

    def __init__(self, total: float, label: str = "", unit: str = "", *,
                 enabled: bool | None = None, delay: float = 0.0, stream=None):
        stream = stream or sys.stderr
        if enabled is None:
            enabled = bool(getattr(stream, "isatty", lambda: False)())
        fraction = not unit
        self.failed = 0
        self._bar = tqdm(total=total, desc=label or None, unit=unit or "it", file=stream,
                         disable=not enabled, delay=delay, leave=False, dynamic_ncols=True,
                         bar_format=("{desc} {bar} {percentage:5.1f}% eta {remaining}"
                                     if fraction else None))

    def __call__(self, fraction: float) -> None:
        """Move a fraction bar to ``fraction`` (0..1 of ``total``)."""
        n = fraction * self._bar.total
        if n > self._bar.n:
            self._bar.update(n - self._bar.n)

    def update(self, status: str | None = None) -> None:
        """Count one unit done; ``status == "failed"`` counts it as failed too."""
        if status == "failed":
            self.failed += 1
            self._bar.set_postfix_str(f"{self.failed} failed", refresh=False)
        self._bar.update(1)

    def close(self) -> None:
        """Erase the bar."""
        self._bar.close()
