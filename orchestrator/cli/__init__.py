"""The ``jitterfmu`` command line.

Each subcommand lives in its own module of this package and defines ``COMMAND`` (its
name), ``HELP`` (one line), ``add_arguments(parser)`` and ``run(args) -> int``.  The CLI
parses and calls library functions, nothing more.  Errors print one sentence (the
exception's message) unless ``--debug`` is given.

A subcommand imports the library inside ``run`` (and ``add_arguments``): building the
parser imports every subcommand module, so an import at their top would load all of the
library (scipy, pyarrow, the experiments) before any command, even ``--help``.
"""

from __future__ import annotations

import argparse
import importlib
import multiprocessing
import pkgutil
import sys
import warnings

#: Longest message printed whole; a longer one (say one that echoes a file) is cut.
MAX_MESSAGE = 2000

# Warnings printed by this process: text -> how many times it was raised.
_SHOWN: dict[str, int] = {}
#: Where the running command keeps the names of the scenario's unconnected inputs (it
#: sets this before the run); the warning then gives their count and this place.
UNCONNECTED_NAMES = {"where": "unconnected_inputs in the run.json that jitterfmu run "
                               "writes for the scenario"}
#: Unconnected inputs named in the warning itself; more are counted.
UNCONNECTED_SHOWN = 3


def clip(text: str, limit: int = MAX_MESSAGE) -> str:
    """``text``, cut in the middle when longer than ``limit`` characters.

    Parameters
    ----------
    text : str
        A message.
    limit : int
        Characters kept.
    """
    if len(text) <= limit:
        return text
    return f"{text[:limit // 2]} [... {len(text) - limit} characters cut ...] {text[-limit // 2:]}"


def unconnected_text(text: str) -> str:
    """The unconnected-inputs warning as the command line says it: the count, at most
    :data:`UNCONNECTED_SHOWN` names, and where all of them are.

    Parameters
    ----------
    text : str
        The library's warning (``"N input(s) are not connected and keep their start
        values: a.u, b.v, ..."``); another text is returned as it is.
    """
    import re

    m = re.fullmatch(r"(\d+) input\(s\) are not connected and keep their start values: "
                     r"(.*)", text, flags=re.S)
    if not m:
        return text
    n, names = int(m[1]), m[2].split(", ")
    if n <= UNCONNECTED_SHOWN:
        return (f"{n} input{'s are' if n > 1 else ' is'} not connected and keep"
                f"{'' if n > 1 else 's'} {'their' if n > 1 else 'its'} start value"
                f"{'s' * (n > 1)}: {', '.join(names)}")
    return (f"{n} inputs are not connected and keep their start values (e.g. "
            f"{', '.join(names[:UNCONNECTED_SHOWN])}); all {n} names: "
            f"{UNCONNECTED_NAMES['where']}")


def _print_warning(text: str, category, times: int = 1, file=None) -> None:
    """One line ``jitterfmu: warning: <text> (<category unless a UserWarning>, N times)``."""
    if getattr(category, "__name__", "") == "UnconnectedInputWarning":
        text = unconnected_text(text)
    notes = [] if issubclass(category, UserWarning) else [category.__name__]
    notes += [f"{times} times"] if times > 1 else []
    note = f" ({', '.join(notes)})" if notes else ""
    out = file or sys.stderr
    out.write(f"jitterfmu: warning: {clip(text)}{note}\n")   # one write: workers share it
    out.flush()


def show_warning(message, category=UserWarning, filename="", lineno=0, file=None,
                 line=None) -> None:
    """Print a warning as one line ``jitterfmu: warning: ...``, once per distinct text.

    Installed as :func:`warnings.showwarning` by the command line (and so in its
    worker processes, which import it): no source line, no file name, no repeats.  In a
    worker, an UnconnectedInputWarning is not printed: it is about the scenario's
    wiring, which the campaign command reports once for the whole run.

    Parameters
    ----------
    message : Warning or str
        What was warned.
    category : type
        The warning's class.
    filename, lineno, file, line
        As :func:`warnings.showwarning` passes them; only ``file`` is used (default
        stderr).
    """
    text = str(message)
    if text in _SHOWN:
        _SHOWN[text] += 1
        return
    _SHOWN[text] = 1
    if (getattr(category, "__name__", "") == "UnconnectedInputWarning"
            and multiprocessing.parent_process() is not None):
        return
    _print_warning(text, category, file=file)


def report_warnings(caught) -> None:
    """Print recorded warnings, each distinct text once, with how often it was raised.

    The texts printed are not printed again by :func:`show_warning` in this process.

    Parameters
    ----------
    caught : list of warnings.WarningMessage
        What :func:`warnings.catch_warnings` recorded.
    """
    counts: dict[str, list] = {}
    for w in caught:
        counts.setdefault(str(w.message), [w.category, 0])[1] += 1
    for text, (category, n) in counts.items():
        _SHOWN[text] = _SHOWN.get(text, 0) + n   # not repeated by show_warning
        _print_warning(text, category, n)


warnings.showwarning = show_warning


def _subcommand_modules():
    mods = []
    for info in pkgutil.iter_modules(__path__):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"{__name__}.{info.name}")
        if hasattr(mod, "COMMAND"):
            mods.append(mod)
    return sorted(mods, key=lambda m: m.COMMAND)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jitterfmu",
        description="Predict and attenuate spacecraft pointing jitter with FMI co-simulation.",
    )
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    from ._options import DefaultsFormatter

    for mod in _subcommand_modules():
        p = sub.add_parser(mod.COMMAND, help=mod.HELP, description=mod.HELP,
                           formatter_class=DefaultsFormatter)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    from ..progress import heartbeat

    try:
        with heartbeat(times=_stage_times()) as beat:
            rc = int(args._run(args) or 0)
            beat.keep = rc == 0   # a failed command's stages did not run to their end
            return rc
    except KeyboardInterrupt:
        print("jitterfmu: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # one clear sentence, traceback only with --debug
        if args.debug:
            raise
        print(f"jitterfmu: error: {clip(_sentence(exc))}", file=sys.stderr)
        print("(run with --debug for the traceback)", file=sys.stderr)
        return 2


def _stage_times():
    """The file of the stages' durations in the user's cache (their time left), or None
    where the cache cannot be used."""
    from fmutools.fmucache import cache_root

    try:
        return cache_root() / "stage_times.json"
    except OSError:   # CacheError included
        return None


def _sentence(exc: BaseException) -> str:
    """The one sentence printed for an error: its message, a file name cut short."""
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        from fmutools.archive import short_repr

        return f"{exc.strerror}: {short_repr(str(exc.filename))}"
    if isinstance(exc, MemoryError):
        return ("out of memory" + (f" ({exc})" if str(exc) else "")
                + "; make the run, its record or its input smaller, or free memory")
    if isinstance(exc, RecursionError):
        return "the input nests too deeply to be read; flatten it"
    return str(exc) or exc.__class__.__name__


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
