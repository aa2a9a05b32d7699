"""``jitterfmu validate``: check FMUs against FMI 2.0 and the project's conventions."""

from __future__ import annotations

import argparse

COMMAND = "validate"
HELP = "validate FMUs (fmpy's checks plus units, dependencies, state, InitialUnknowns)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("fmus", nargs="+", metavar="FILE.fmu", help="FMU files")


def run(args: argparse.Namespace) -> int:
    from fmukit.validate import validate_fmu

    bad = 0
    for path in args.fmus:
        problems = validate_fmu(path)
        for problem in problems:
            print(problem)
        bad += bool(problems)
    return 1 if bad else 0
