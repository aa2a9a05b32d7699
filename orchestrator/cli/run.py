"""``jitterfmu run``: co-simulate a scenario (TOML or SSP) and write its results."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

COMMAND = "run"
HELP = "co-simulate a scenario (.toml or .ssp) and write results.parquet and run.json"


def add_arguments(parser) -> None:
    """Declare the options of ``jitterfmu run``."""
    import argparse

    from ._options import Deprecated, add_fmu_dir, add_out, add_stop

    parser.add_argument("scenario", help="scenario file (.toml) or SSP archive (.ssp)")
    add_out(parser, "<scenario file name without .toml>",
            "output folder for the results file and run.json")
    add_stop(parser)
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="INST.VAR=VALUE", help="set a start value (repeatable)")
    parser.add_argument("--algorithm", choices=["gauss-seidel", "jacobi"], default=None,
                        help="order of the FMUs within a step: gauss-seidel (along the "
                             "feedthrough graph, each FMU sees the outputs computed before "
                             "it) or jacobi (every FMU sees the previous step's outputs) "
                             "(default: the scenario's [experiment] algorithm, else "
                             "gauss-seidel)")
    parser.add_argument("--format", choices=("parquet", "csv", "mat"), default=None,
                        dest="fmt", help="results file: results.parquet (default, units in "
                        "its metadata), results.csv (header 'name [unit]') or results.mat "
                        "(MATLAB: a struct per instance)")
    parser.add_argument("--csv", dest="fmt", action=Deprecated, nargs=0, const="csv",
                        new="--format csv", help=argparse.SUPPRESS)
    add_fmu_dir(parser)
    parser.add_argument("--python-fmus", action="store_const", const="python",
                        dest="fmu_kind", default=None,
                        help="run the Python build of the suite's FMUs (FMU_DIR/python/) "
                             "instead of the native ones")
    parser.add_argument("--overwrite", action="store_true",
                        help="discard the rows an unfinished (killed) run left in --out")
    parser.add_argument("--quiet", action="store_true",
                        help="no start line and no progress bar or lines")


def run(args) -> int:
    """Run the scenario; return 0, or 1 when the run failed part-way or ended unstable."""
    # deferred: the parser imports every subcommand (orchestrator.cli)
    from orchestrator import SimulationError, run_scenario
    from orchestrator.scenario import parse_override

    from . import UNCONNECTED_NAMES

    out = Path(args.out) if args.out else Path("out") / Path(args.scenario).stem
    UNCONNECTED_NAMES["where"] = f"{out / 'run.json'} (unconnected_inputs)"
    if not args.quiet:
        from orchestrator.progress import stage

        from ._options import shown

        stage(f"run {shown(args.scenario)}: co-simulating")
    overrides = dict(parse_override(s) for s in args.overrides)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result = run_scenario(args.scenario, out, stop_time=args.stop,
                                  overrides=overrides, algorithm=args.algorithm,
                                  quiet=args.quiet, fmu_dir=args.fmu_dir,
                                  fmu_kind=args.fmu_kind, overwrite=args.overwrite,
                                  fmt=args.fmt)
        except SimulationError as exc:
            _warn(caught)
            rows = len(exc.result.table["time"]) if exc.result else 0
            print(f"jitterfmu: error: {exc}", file=sys.stderr)
            print(f"jitterfmu: the {rows} rows recorded so far are in {out}", file=sys.stderr)
            return 1
        except KeyboardInterrupt:   # SIGINT: the run wrote its rows before it ended
            _warn(caught)
            print(f"jitterfmu: interrupted; {_kept(out)}", file=sys.stderr)
            return 130
    _warn(caught)
    meta = result.metadata
    name = f"results.{meta['format']}"
    print(f"{meta['rows']} rows x {len(result.table) - 1} variables in {out / name} "
          f"({meta['wall_time_s']:.2f} s wall)")
    if meta.get("status") == "unstable":   # a loop held by its limits: not a result
        print(f"jitterfmu: unstable: {meta['unstable']['message']}", file=sys.stderr)
        return 1
    return 0


def _kept(out: Path) -> str:
    """Where the rows of an interrupted run are, from its run.json."""
    import json

    try:
        meta = json.loads((out / "run.json").read_text(encoding="utf-8"))
        rows, name = meta["rows"], out / f"results.{meta['format']}"
    except (OSError, ValueError, KeyError, TypeError):
        return f"the rows recorded so far, if any, are in {out}"
    return f"the {rows} rows recorded so far are in {name}"


def _warn(caught) -> None:
    from orchestrator.linearcheck import UnstableLoopWarning

    from . import report_warnings

    # the linear engine's verdict is the run's "unstable:" line, said once
    report_warnings([w for w in caught if not issubclass(w.category, UnstableLoopWarning)])
