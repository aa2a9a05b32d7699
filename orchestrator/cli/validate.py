"""``jitterfmu validate``: check FMUs against FMI 2.0 and the project's conventions."""

from __future__ import annotations

import argparse

COMMAND = "validate"
HELP = ("validate FMUs: FMI 2.0 errors fail; the project's conventions (units, "
        "dependencies, state, InitialUnknowns) warn, or fail with --strict")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("fmus", nargs="+", metavar="FILE.fmu",
                        help="FMU files, or SSP archives (each component FMU is checked)")
    parser.add_argument("--strict", action="store_true",
                        help="fail on the project's conventions too (as the build does)")


def run(args: argparse.Namespace) -> int:
    """Print one line per problem; return 1 if any FMU fails, else 0."""
    # deferred: the parser imports every subcommand (orchestrator.cli)
    from fmutools.validate import check_fmu

    bad = checked = warned = 0
    for path in _fmus(args.fmus):
        checked += 1
        if isinstance(path, Exception):
            print(f"error: {path}")
            bad += 1
            continue
        errors, warnings = check_fmu(path)
        for problem in errors:
            print(f"error: {problem}")
        for problem in warnings:
            print(f"{'error' if args.strict else 'warning'}: {problem} "
                  "(a convention of this project, not of FMI 2.0)")
        failed = bool(errors) or (args.strict and bool(warnings))
        bad += failed
        warned += bool(warnings) and not failed
    noun = "FMU" if checked == 1 else "FMUs"
    if bad:
        if checked > 1:   # one FMU's error line says it all
            print(f"{bad} of {checked} {noun} invalid")
    else:
        print(f"{checked} {noun} valid" + (f" ({warned} with warnings)" if warned else ""))
    return 1 if bad else 0


def _fmus(paths):
    """The FMU files to check: each FMU, and each component FMU of an SSP archive.

    An archive that cannot be read (say one whose component sources leave it) yields
    its error instead.
    """
    from orchestrator.scenario import ScenarioError, read_ssp

    for path in paths:
        if not str(path).lower().endswith(".ssp"):
            yield path
            continue
        try:
            scenario = read_ssp(path)
        except ScenarioError as exc:
            yield exc
            continue
        yield from dict.fromkeys(i.fmu for i in scenario.instances)
