"""``jitterfmu build``: build and validate the project's FMUs."""

from __future__ import annotations

import argparse
import sys

COMMAND = "build"
HELP = "build every FMU of the project (or the named ones) and validate them"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="fmus", help="output folder (default: fmus/)")
    parser.add_argument("--model", action="append", metavar="NAME",
                        help="modelIdentifier to build (repeatable; default: all); with "
                        "--structure, the identifier of that FMU")
    parser.add_argument("--structure", metavar="MODEL.npz",
                        help="build only a structure FMU from a reduced model file (e.g. from "
                        "'jitterfmu import-nastran'), named <stem>_structure unless --model")


def run(args: argparse.Namespace) -> int:
    from fmukit.registry import build_all

    if args.structure:
        from structfmu.fmuspec import build_structure_fmu

        if args.model and len(args.model) > 1:
            raise ValueError("--structure builds one FMU; give at most one --model")
        report = build_structure_fmu(args.structure, args.out,
                                     args.model[0] if args.model else None)
        print(f"{report.fmus[0]} {'ok' if not report.problems else 'has problems'}")
        for problem in report.problems:
            print(problem, file=sys.stderr)
        return 1 if report.problems else 0
    report = build_all(args.out, args.model, progress=print)
    for problem in report.problems:
        print(problem, file=sys.stderr)
    if not report.fmus:
        print("no FMU to build: no package provides an fmuspec module", file=sys.stderr)
        return 1
    return 1 if report.problems else 0
