"""The options every command spells the same way, and the help that shows each default.

One vocabulary across commands: ``--stop S`` (simulated time), ``--out DIR`` (the
output folder, ``out/<name>`` by default), ``--fmu-dir DIR`` (searched first for FMUs),
``--workers N`` (processes; the number of CPUs by default).  An old spelling stays an
alias for a release and prints a one-line note when used (:class:`Deprecated`).
"""

from __future__ import annotations

import argparse
import os
import sys

__all__ = ["DefaultsFormatter", "Deprecated", "add_fmu_dir", "add_out", "add_stop",
           "add_workers", "cpu_workers", "shown"]

#: Option names whose help must say their default in words when it is not a value
#: (tests/orchestrator/test_cli_vocabulary.py holds every command to it).
VOCABULARY = ("--stop", "--out", "--fmu-dir", "--workers", "--algorithm", "--samples",
              "--engine", "--verify", "--format")


class DefaultsFormatter(argparse.HelpFormatter):
    """Help that ends each option with its default, unless its text already says it."""

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if ("default" in text or not action.option_strings or default is None
                or default is argparse.SUPPRESS or isinstance(default, bool)
                or default == [] or action.nargs == 0):
            return text
        shown = " ".join(map(str, default)) if isinstance(default, (list, tuple)) \
            else "%(default)s"
        return f"{text} (default: {shown})" if text else f"default: {shown}"


class Deprecated(argparse.Action):
    """An old spelling of an option: stores as the new one, says so in one line.

    Give it ``dest`` of the new option and ``new`` (its spelling) as a keyword:
    ``parser.add_argument("--stop-time", dest="stop", action=Deprecated, new="--stop",
    type=float, help=argparse.SUPPRESS)``; a flag takes ``nargs=0`` and stores ``const``.
    """

    def __init__(self, option_strings, dest, new: str = "", **kwargs):
        self.new = new
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"jitterfmu: note: {option_string} is an old spelling of {self.new}, kept "
              f"for one release; use {self.new}", file=sys.stderr)
        setattr(namespace, self.dest, self.const if self.nargs == 0 else values)


def shown(path) -> str:
    """A path from the command line as a start line echoes it: quoted, and cut in the
    middle when longer than about 80 characters.

    Parameters
    ----------
    path : path-like or str
    """
    from fmutools.archive import short_repr

    return short_repr(str(path))


def cpu_workers() -> int:
    """The default worker count: the number of CPUs of this machine (at least 1)."""
    return os.cpu_count() or 1


def add_stop(parser, what: str = "the scenario's [experiment] stop", lead: str = "") -> None:
    """``--stop S`` (old spelling ``--stop-time``): the simulated stop time.

    Parameters
    ----------
    parser : argparse.ArgumentParser
    what : str
        What stands when it is not given.
    lead : str
        Text before the help's own (``"with --reference: "``).
    """
    parser.add_argument("--stop", type=float, default=None, metavar="S",
                        help=f"{lead}stop time of the co-simulation (s; default: {what})")
    parser.add_argument("--stop-time", dest="stop", type=float, action=Deprecated,
                        new="--stop", help=argparse.SUPPRESS)


def add_out(parser, name: str, what: str = "output folder", **kwargs) -> None:
    """``--out DIR``: the output folder, ``out/<name>`` by default.

    Parameters
    ----------
    parser : argparse.ArgumentParser
    name : str
        What names the default folder (``"<scenario name>"``).
    what : str
        What the folder holds; ``kwargs`` go to ``add_argument`` (e.g. ``type``).
    """
    parser.add_argument("--out", default=None, metavar="DIR",
                        help=f"{what} (default: out/{name})", **kwargs)


def add_fmu_dir(parser, builds: bool = False) -> None:
    """``--fmu-dir DIR``: the folder searched first for FMUs.

    Parameters
    ----------
    parser : argparse.ArgumentParser
    builds : bool
        The command builds the suite's FMUs it lacks into it (``reproduce``).
    """
    if builds:
        text = ("folder searched first for FMUs; the suite's FMUs missing or stale in it "
                "are built into it (default: fmus)")
    else:
        text = ("folder searched first for FMUs (default: none; then fmus/ beside the "
                "scenario, the scenario's folder, fmus/ of its parent and of the current "
                "folder)")
    parser.add_argument("--fmu-dir", default=None, metavar="DIR", help=text)


def add_workers(parser, note: str = "") -> None:
    """``--workers N``: worker processes, the number of CPUs by default.

    Parameters
    ----------
    parser : argparse.ArgumentParser
    note : str
        What else the help says (e.g. ``"; 0 = in this process"``).
    """
    parser.add_argument("--workers", type=int, default=None, metavar="N",
                        help=f"worker processes (default: the number of CPUs, "
                             f"{cpu_workers()} here{note})")
