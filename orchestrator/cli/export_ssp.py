"""``jitterfmu export-ssp``: write a scenario as an SSP 1.0 archive."""

from __future__ import annotations

import warnings

COMMAND = "export-ssp"
HELP = "export a scenario as an SSP 1.0 archive (FMUs, parameters, OSP rate annotations)"


def add_arguments(parser) -> None:
    """Declare the options of ``jitterfmu export-ssp``."""
    from ._options import add_fmu_dir

    parser.add_argument("scenario", help="scenario file (.toml)")
    parser.add_argument("out", help="SSP archive to write (.ssp)")
    add_fmu_dir(parser)


def run(args) -> int:
    """Export the scenario; return 0."""
    # deferred: the parser imports every subcommand (orchestrator.cli)
    from orchestrator import load_scenario, prepare, write_ssp

    from . import report_warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        path = write_ssp(prepare(load_scenario(args.scenario), args.fmu_dir), args.out)
    report_warnings(caught)
    print(f"wrote {path}")
    return 0
