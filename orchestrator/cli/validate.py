"""``jitterfmu validate``: check FMUs against FMI 2.0 and the project's conventions."""

from __future__ import annotations

import argparse

COMMAND = "validate"
HELP = ("validate FMUs: FMI 2.0 errors fail; the project's conventions (units, "
        "dependencies, state, InitialUnknowns) warn, or fail with --strict")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("fmus", nargs="+", metavar="FILE.fmu", help="FMU files")
    parser.add_argument("--strict", action="store_true",
                        help="fail on the project's conventions too (as the build does)")


def run(args: argparse.Namespace) -> int:
    """Print one line per problem; return 1 if any FMU fails, else 0."""
    # deferred: the parser imports every subcommand (orchestrator.cli)
    from fmutools.validate import check_fmu

    bad = 0
    for path in args.fmus:
        errors, warnings = check_fmu(path)
        for problem in errors:
            print(f"error: {problem}")
        for problem in warnings:
            print(f"{'error' if args.strict else 'warning'}: {problem} "
                  "(a convention of this project, not of FMI 2.0)")
        bad += bool(errors) or (args.strict and bool(warnings))
    return 1 if bad else 0
