"""The one progress report of the project, for runs, campaigns and experiments.

A run reports the fraction of its simulated time; a campaign counts its cases and the
failed ones.  On a terminal the report is a bar on stderr (tqdm) that appears after
``delay`` seconds and is erased when closed.  When stderr is not a terminal (a log, a
CI job) it is a line at most every :data:`LOG_EVERY` seconds with what is done and an
estimate of the time left, so a long command is never silent.  A clock thread keeps
both alive while nothing finishes: the bar's elapsed time moves every second, and a line
comes every ``every`` seconds even while one long case or sample is still running.
:func:`stage` prints one line when a stage of a long command starts; while a command
holds :func:`heartbeat` open, a stage that runs longer than ``every`` seconds with no bar
and no other line says it is still running, so even a stage without a count is never
silent longer than that.  A stage has no count, so its time left comes from the last
time the same stage ran to its end on this machine (kept by the command line in the
user's cache, ``stage_times.json``): "about 0:35 left (1:20 when last run here)", or
"time left unknown" the first time.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
import threading
import time
import types
from pathlib import Path

from tqdm import tqdm

__all__ = ["LOG_EVERY", "ProgressBar", "heartbeat", "stage"]

#: Seconds of silence before a progress line when stderr is not a terminal (env
#: ``JITTERFMU_LOG_EVERY``, at most this): the clocks look every second, so no two lines
#: are more than 30 s apart.
LOG_EVERY = 29.0
#: Seconds between redraws of a terminal bar while nothing finishes.
REDRAW_EVERY = 1.0


def _every() -> float:
    """The line interval: ``$JITTERFMU_LOG_EVERY`` when it is a number in (0, 29], else 29."""
    try:
        value = float(os.environ.get("JITTERFMU_LOG_EVERY", LOG_EVERY))
    except ValueError:
        return LOG_EVERY
    return value if 0 < value <= LOG_EVERY else LOG_EVERY


def _is_terminal(stream) -> bool:
    return bool(getattr(stream, "isatty", lambda: False)())


def _clock(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}" if s >= 3600 else \
        f"{s // 60}:{s % 60:02d}"


class ProgressBar:
    """Progress over ``total`` units: a bar on a terminal, timed lines otherwise.

    Parameters
    ----------
    total : float
        Units at the end (1.0 for a fraction of a run; the number of cases).
    label : str
        Text before the bar.
    unit : str
        Name of one unit (``"case"``); empty for a fraction.
    enabled : bool, optional
        True: the bar, even off a terminal; False: nothing; default: the bar on a
        terminal, a line every ``every`` seconds elsewhere.
    delay : float
        Seconds before the bar first appears (s).
    stream : file, optional
        Default ``sys.stderr``.
    every : float, optional
        Seconds between lines off a terminal (default :data:`LOG_EVERY`).
    """

    def __init__(self, total: float, label: str = "", unit: str = "", *,
                 enabled: bool | None = None, delay: float = 0.0, stream=None,
                 every: float | None = None):
        stream = stream or sys.stderr
        self._lines = enabled is None and not _is_terminal(stream)
        if enabled is None:
            enabled = _is_terminal(stream)
        fraction = not unit
        self.failed = 0
        self._stream, self._label, self._unit, self._total = stream, label, unit, total
        self._t0 = time.monotonic()
        # its first line: `every` s after the command's last line while a command holds
        # the heartbeat open, else `every` s after the bar starts
        self._last = -math.inf if _BEAT.active else self._t0
        self._done = 0.0
        self._every = _every() if every is None else every
        self._lock = threading.Lock()
        self._delay = delay
        self._bar = tqdm(total=total, desc=label or None, unit=unit or "it", file=stream,
                         disable=not enabled, delay=delay, leave=False, dynamic_ncols=True,
                         bar_format=("{desc} {bar} {percentage:5.1f}% eta {remaining}"
                                     if fraction else None))
        self._stop = threading.Event()
        self._clock = None
        if self._lines or (enabled and total):
            self._clock = threading.Thread(target=self._tick, daemon=True,
                                           name=f"progress {label}")
            _BEAT.bar(+1)
            self._clock.start()

    def __call__(self, fraction: float) -> None:
        """Move a fraction bar to ``fraction`` (0..1 of ``total``)."""
        n = fraction * self._bar.total
        with self._lock:
            if n > self._bar.n:
                self._bar.update(n - self._bar.n)
            self._done = max(self._done, n)
            self._log()

    def update(self, status: str | None = None) -> None:
        """Count one unit done; ``status == "failed"`` counts it as failed too."""
        with self._lock:
            if status == "failed":
                self.failed += 1
                self._bar.set_postfix_str(f"{self.failed} failed", refresh=False)
            self._bar.update(1)
            self._done += 1
            self._log()

    def _tick(self) -> None:
        """The clock thread: a due line, or a redrawn bar, while nothing finishes."""
        period = min(REDRAW_EVERY, self._every) if self._every > 0 else REDRAW_EVERY
        try:
            while not self._stop.wait(period):
                with self._lock:
                    if self._stop.is_set() or self._done >= self._total:
                        return   # closed, or all done (a bar left open falls silent)
                    if self._lines:
                        self._log(waiting=True)
                    elif time.monotonic() - self._t0 >= self._delay:
                        self._bar.refresh()
                        self._bar.last_print_t = self._bar._time()   # so close() erases it
        finally:
            _BEAT.bar(-1)   # the heartbeat speaks again once no bar is alive

    def _log(self, waiting: bool = False) -> None:
        """A line off a terminal once ``every`` seconds passed without one from this bar
        or any other line of the command (the clock thread's ``waiting`` lines come also
        before the first unit is done)."""
        if not self._lines:
            return
        now = time.monotonic()
        if now - max(self._last, _BEAT.last) < self._every or not (self._done or waiting):
            return
        self._last = now
        elapsed = now - self._t0
        if self._unit:
            done = f"{int(self._done)}/{int(self._total)} {self._unit}s"
            if self.failed:
                done += f", {self.failed} failed"
        else:
            done = f"{100 * self._done / self._total:.0f} %"
        left = (f"about {_clock(elapsed * (self._total - self._done) / self._done)} left"
                if self._done else f"time left known after the first {self._unit or 'step'}")
        print(f"{self._label}: {done}, {_clock(elapsed)} elapsed, {left}",
              file=self._stream, flush=True)
        _BEAT.said()

    def close(self) -> None:
        """Stop the clock and erase the bar."""
        self._stop.set()
        with self._lock:
            self._bar.close()


def stage(message: str, stream=None) -> None:
    """Say on stderr, in one line, that a stage of a long command starts.

    Parameters
    ----------
    message : str
        What starts, e.g. ``"testbed-isolation: designing the mount #3 gains"``.
    stream : file, optional
        Default ``sys.stderr``.
    """
    print(f"jitterfmu: {message}", file=stream or sys.stderr, flush=True)
    _BEAT.stage(message)


# stages whose durations a store keeps (the most recent ones)
_KEEP_STAGES = 500


def _read_times(path) -> dict:
    """``{stage message: seconds}`` from ``path``; anything else there is ignored."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    if not isinstance(data, dict):
        return {}
    return {k: float(v) for k, v in data.items() if isinstance(k, str)
            and isinstance(v, (int, float)) and not isinstance(v, bool)
            and math.isfinite(v) and v >= 0}


def _write_times(path, times: dict) -> None:
    """Write the most recent ``times`` to ``path`` whole (atomically)."""
    from .files import write_json_atomic

    with contextlib.suppress(OSError):   # a cache not written costs only the estimate
        write_json_atomic(path, dict(list(times.items())[-_KEEP_STAGES:]), indent=0)


def _left(elapsed: float, before: float | None) -> str:
    """What a still-running line says of the time left of a stage that took ``before``
    seconds when it last ran to its end here (None: never)."""
    if before is None:
        return " (time left unknown: not run to its end here before)"
    if elapsed < before:
        return f", about {_clock(before - elapsed)} left ({_clock(before)} when last run here)"
    return f", past the {_clock(before)} it took when last run here"


class _Heartbeat:
    """The last stage said, and a thread that says it is still running (one per process)."""

    def __init__(self):
        self.lock = threading.Lock()
        self.message = None
        self.t0 = self.last = time.monotonic()
        self.bars = 0
        self.active = False
        self.times = None      # {message: seconds} of stages run to their end, or None
        self.before = None     # the running stage's seconds when last run here

    def stage(self, message: str) -> None:
        with self.lock:
            now = time.monotonic()
            self._ended(now)
            self.message, self.t0 = message, now
            self.last = self.t0
            self.before = None if self.times is None else self.times.get(message)

    def _ended(self, now: float) -> None:
        """The running stage ran to its end at ``now``: its time is kept (the lock held)."""
        if self.times is not None and self.message is not None:
            self.times.pop(self.message, None)   # the most recent last
            self.times[self.message] = now - self.t0

    def said(self) -> None:
        with self.lock:
            self.last = time.monotonic()

    def bar(self, change: int) -> None:
        with self.lock:
            self.bars += change

    def run(self, stop: threading.Event, stream, every: float) -> None:
        while not stop.wait(min(REDRAW_EVERY, every)):
            with self.lock:
                now = time.monotonic()
                if self.message is None or self.bars > 0 or now - self.last < every:
                    continue
                self.last = now
                line = (f"jitterfmu: {self.message}: still running, "
                        f"{_clock(now - self.t0)} elapsed"
                        f"{'' if self.times is None else _left(now - self.t0, self.before)}")
            print(line, file=stream, flush=True)


_BEAT = _Heartbeat()


@contextlib.contextmanager
def heartbeat(stream=None, every: float | None = None, times=None):
    """While open, a stage (:func:`stage`) that runs ``every`` seconds with no progress
    bar alive and no line said says it is still running, with its time so far and, when
    ``times`` knows it, its time left.

    The command line holds it open for the length of a command.

    Parameters
    ----------
    stream : file, optional
        Default ``sys.stderr`` (as it is when the heartbeat starts).
    every : float, optional
        Seconds of silence before a line (default :data:`LOG_EVERY`, or
        ``$JITTERFMU_LOG_EVERY`` up to it).
    times : path, optional
        A JSON file of the stages' durations when last run to their end: read when the
        heartbeat opens, rewritten when it closes after a command that ended normally
        (a stage cut short by an error or an interrupt, or one of a command that set
        ``keep = False`` on the object yielded, is not kept).  None keeps none.
    """
    stop = threading.Event()
    with _BEAT.lock:
        _BEAT.message, _BEAT.active = None, True
        _BEAT.last = time.monotonic()
        _BEAT.times = None if times is None else _read_times(times)
    thread = threading.Thread(target=_BEAT.run, daemon=True, name="heartbeat",
                              args=(stop, stream or sys.stderr,
                                    _every() if every is None else every))
    thread.start()
    beat = types.SimpleNamespace(keep=True)   # keep = False: a failed command
    ended = False
    try:
        yield beat
        ended = beat.keep
    finally:
        stop.set()
        thread.join()
        with _BEAT.lock:
            if ended and _BEAT.times is not None:
                _BEAT._ended(time.monotonic())
                _write_times(times, _BEAT.times)
            _BEAT.active, _BEAT.times, _BEAT.message = False, None, None
