"""``jitterfmu build``: build and validate the project's FMUs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

COMMAND = "build"
HELP = "build every FMU of the project (or the named ones), native and Python, and validate"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``jitterfmu build``."""
    parser.add_argument("--out", default="fmus",
                        help="FMU folder (default: fmus/): the native FMUs in it, their "
                        "Python twins in its python/ subfolder")
    parser.add_argument("--model", action="append", metavar="NAME",
                        help="modelIdentifier to build (repeatable; default: all); with "
                        "--structure, the identifier of that FMU")
    parser.add_argument("--structure", metavar="MODEL.npz",
                        help="build only a structure FMU from a reduced model file (e.g. from "
                        "'jitterfmu import-nastran'), named <stem>_structure unless --model")
    only = parser.add_mutually_exclusive_group()
    only.add_argument("--native", action="store_true",
                      help="only the native (C99) FMUs, into --out itself "
                      "(docs/native-fmus.md)")
    only.add_argument("--python", action="store_true",
                      help="only the Python (pythonfmu) FMUs, into --out/python/")


def run(args: argparse.Namespace) -> int:
    """Build; return 0, or 1 when an FMU has validation problems."""
    # deferred: the parser imports every subcommand (orchestrator.cli)
    from fmutools import PYTHON_SUBDIR
    from fmutools.ensure import record_built
    from fmutools.registry import build_all
    from nativefmu.build import build_all_native, build_native_structure
    from structfmu.fmuspec import build_structure_fmu

    out = Path(args.out)
    py_dir = out / PYTHON_SUBDIR
    if args.structure and args.model and len(args.model) > 1:
        raise ValueError("--structure builds one FMU; give at most one --model")
    name = args.model[0] if (args.structure and args.model) else None
    problems, built, skipped = [], [], ()
    if not args.native:
        if args.structure:
            report = build_structure_fmu(args.structure, py_dir, name)
            print(f"{report.fmus[0]} {'ok' if not report.problems else 'has problems'}")
        else:
            report = build_all(py_dir, args.model, progress=print)
            if not report.fmus:
                print("no FMU to build: no package provides an fmuspec module", file=sys.stderr)
                return 1
            record_built(py_dir, [p.stem for p in report.fmus], "python")
        problems += report.problems
        built += report.fmus
    if not args.python:
        if args.structure:
            report = build_native_structure(args.structure, out, name)
            print(f"{report.fmus[0]} (native) {'ok' if not report.problems else 'has problems'}")
        else:
            report = build_all_native(out, args.model, progress=print,
                                      python_dir=None if args.native else py_dir)
            record_built(out, [p.stem for p in report.fmus], "native")
        problems += report.problems
        built += report.fmus
        skipped = report.skipped
    for problem in problems:
        print(problem, file=sys.stderr)
    if skipped:
        print(f"no native kernel for {', '.join(skipped)}; their Python FMUs are in "
              f"{py_dir}", file=sys.stderr)
    return 1 if problems or not built else 0
