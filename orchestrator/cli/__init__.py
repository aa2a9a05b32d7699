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
import pkgutil
import sys


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
    for mod in _subcommand_modules():
        p = sub.add_parser(mod.COMMAND, help=mod.HELP, description=mod.HELP)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    try:
        return int(args._run(args) or 0)
    except KeyboardInterrupt:
        print("jitterfmu: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # one clear sentence, traceback only with --debug
        if args.debug:
            raise
        msg = str(exc) or exc.__class__.__name__
        print(f"jitterfmu: error: {msg}", file=sys.stderr)
        print("(run with --debug for the traceback)", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
