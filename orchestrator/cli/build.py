"""``jitterfmu build``: build and validate the project's FMUs."""

from __future__ import annotations

import argparse
import sys

COMMAND = "build"
HELP = "build every FMU of the project (or the named ones) and validate them"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", help="output folder (default: fmus/, or build/native-fmus/ "
                        "with --native)")
    parser.add_argument("--model", action="append", metavar="NAME",
                        help="modelIdentifier to build (repeatable; default: all); with "
                        "--structure, the identifier of that FMU")
    parser.add_argument("--structure", metavar="MODEL.npz",
                        help="build only a structure FMU from a reduced model file (e.g. from "
                        "'jitterfmu import-nastran'), named <stem>_structure unless --model")
    parser.add_argument("--native", action="store_true",
                        help="build the native (C99) FMUs instead: same names and variables, "
                        "no Python needed to run them (docs/native-fmus.md)")


def run(args: argparse.Namespace) -> int:
    from fmutools.registry import build_all

    if args.native:
        return _run_native(args)
    args.out = args.out or "fmus"
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


def _run_native(args: argparse.Namespace) -> int:
    from nativefmu.build import build_all_native, build_native_structure

    args.out = args.out or "build/native-fmus"  # never over the Python FMUs by default
    if args.structure:
        if args.model and len(args.model) > 1:
            raise ValueError("--structure builds one FMU; give at most one --model")
        report = build_native_structure(args.structure, args.out,
                                        args.model[0] if args.model else None)
        print(f"{report.fmus[0]} (native) {'ok' if not report.problems else 'has problems'}")
    else:
        report = build_all_native(args.out, args.model, progress=print)
    for problem in report.problems:
        print(problem, file=sys.stderr)
    if report.skipped:
        print(f"no native kernel for {', '.join(report.skipped)}; build their Python FMUs "
              "with 'jitterfmu build'", file=sys.stderr)
    return 1 if report.problems or not report.fmus else 0
