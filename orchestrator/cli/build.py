"""``jitterfmu build``: build and validate the project's FMUs."""

from __future__ import annotations

import argparse
import sys

COMMAND = "build"
HELP = "build every FMU of the project (or the named ones) and validate them"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="fmus", help="output folder (default: fmus/)")
    parser.add_argument("--model", action="append", metavar="NAME",
                        help="modelIdentifier to build (repeatable; default: all)")


def run(args: argparse.Namespace) -> int:
    from fmukit.registry import build_all

    report = build_all(args.out, args.model, progress=print)
    for problem in report.problems:
        print(problem, file=sys.stderr)
    if not report.fmus:
        print("no FMU to build: no package provides an fmuspec module", file=sys.stderr)
        return 1
    return 1 if report.problems else 0
