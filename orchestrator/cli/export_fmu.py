"""``jitterfmu export-fmu``: write a scenario as one FMI 2.0 or 3.0 co-simulation FMU."""

from __future__ import annotations

import warnings

COMMAND = "export-fmu"
HELP = ("export a scenario as one FMU: its native FMUs and the master's schedule in C "
        "(FMI 2.0 or 3.0 co-simulation)")


def add_arguments(parser) -> None:
    """Declare the options of ``jitterfmu export-fmu``."""
    parser.add_argument("scenario", help="scenario file (.toml or .ssp)")
    parser.add_argument("out", help="FMU to write (.fmu); its stem is the modelIdentifier")
    parser.add_argument("--output", action="append", default=None, metavar="INST.VAR",
                        help="an output of the FMU (repeatable); default: the scenario's "
                             "[record] variables")
    parser.add_argument("--parameter", action="append", default=[], metavar="INST.NAME",
                        help="an inner parameter exposed as the FMU's (repeatable)")
    from ._options import add_fmu_dir

    add_fmu_dir(parser)
    parser.add_argument("--fmi", type=int, choices=(2, 3), default=2,
                        help="FMI version of the FMU (default 2; the inner FMUs are the "
                             "FMI 2.0 native build either way)")
    parser.add_argument("--no-windows", action="store_true",
                        help="no win64 binary even when mingw-w64 is installed")


def run(args) -> int:
    """Export the scenario; return 0."""
    # deferred: the parser imports every subcommand (orchestrator.cli)
    from nativefmu.container import export_fmu

    from ..progress import stage
    from . import report_warnings
    from ._options import shown

    stage(f"export-fmu {shown(args.scenario)}: compiling its native FMUs and the master's "
          f"schedule into {shown(args.out)} (FMI {args.fmi}.0)")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        path = export_fmu(args.scenario, args.out, outputs=args.output,
                          parameters=args.parameter, fmu_dir=args.fmu_dir,
                          windows=False if args.no_windows else None, fmi=args.fmi)
    report_warnings(caught)
    print(f"wrote {path}")
    return 0
