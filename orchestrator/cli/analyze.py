"""``jitterfmu analyze``: the linear closed loop of a scenario, before tuning it."""

from __future__ import annotations

COMMAND = "analyze"
HELP = ("linear closed loop of a scenario: poles and damping, decay of a mode, gain "
        "margins per loop, ideal ceiling of a performance output")


def add_arguments(parser) -> None:
    """Declare the options of ``jitterfmu analyze``."""
    parser.add_argument("scenario", help="scenario file (.toml) or SSP archive (.ssp)")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="INST.VAR=VALUE", help="set a start value (repeatable)")
    parser.add_argument("--fmu-dir", default=None, help="folder searched first for FMUs")
    parser.add_argument("--open", action="append", default=[], metavar="INST",
                        help="take an instance out of the loop (its outputs held at zero), "
                             "e.g. a slow ACS whose period hides faster poles (repeatable)")
    parser.add_argument("--mode", type=float, action="append", default=[], metavar="HZ",
                        help="report the decay of the pole nearest this mode (repeatable)")
    parser.add_argument("--band", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                        help="list the closed-loop poles in this band (Hz)")
    parser.add_argument("--no-margins", action="store_true", help="skip the gain margins")
    parser.add_argument("--performance", action="append", default=[], metavar="INST.VAR",
                        help="output whose ideal ceiling to compute (repeatable)")
    parser.add_argument("--disturbance", default=None, metavar="INST.VAR",
                        help="source output carrying the disturbance (for the ceiling)")
    parser.add_argument("--freq", type=float, action="append", default=[], metavar="HZ",
                        help="disturbance line (Hz, repeatable)")
    parser.add_argument("--actuator", action="append", default=[], metavar="CONTROLLER",
                        help="controller instance whose command is free in the ceiling "
                             "(repeatable; default: every controller)")
    parser.add_argument("--method", choices=["cancel", "optimal", "both"], default="both",
                        help="ceiling: cancel the controllers' sensors, or best commands")
    parser.add_argument("--reference", action="store_true",
                        help="compare with the sampled-data reference (continuous structure "
                             "and amplifiers, the controllers at their rates): what the "
                             "partition adds to each loop at its crossover, and the "
                             "co-simulated outputs against it")
    parser.add_argument("--stop", type=float, default=None, metavar="S",
                        help="with --reference: co-simulate this long (s; default the "
                             "scenario's stop time)")
    parser.add_argument("--output", action="append", default=[], metavar="INST.VAR",
                        help="with --reference: output to compare (repeatable; default the "
                             "scenario's [record])")


def run(args) -> int:
    """Print the analysis; return 0."""
    # deferred: the parser imports every subcommand (orchestrator.cli)
    from orchestrator.analysis import AnalysisError, ceiling, linearize, report
    from orchestrator.scenario import parse_override

    overrides = dict(parse_override(s) for s in args.overrides)
    if args.reference:
        from orchestrator import reference

        res = reference.check(args.scenario, args.output or None, stop_time=args.stop,
                              overrides=overrides, fmu_dir=args.fmu_dir, opened=args.open)
        print(reference.report(res))
        return 0
    lin = linearize(args.scenario, overrides=overrides, fmu_dir=args.fmu_dir)
    if args.open:
        lin = lin.opened(args.open)
    print(report(lin, modes=args.mode, margins=not args.no_margins, band=args.band))
    if args.performance:
        if not (args.disturbance and args.freq):
            raise AnalysisError("a ceiling needs --disturbance INST.VAR and at least one "
                                "--freq HZ")
        actuators = args.actuator or lin.controllers()
        methods = ("cancel", "optimal") if args.method == "both" else (args.method,)
        print()
        print(f"ideal ceiling of {', '.join(args.performance)} under {args.disturbance} "
              f"at {', '.join(f'{f:g}' for f in args.freq)} Hz, actuators "
              f"{', '.join(actuators)}")
        for m in methods:
            c = ceiling(lin, args.performance, args.disturbance, args.freq,
                        actuators=actuators, method=m)
            what = ("cancel the controllers' sensors" if m == "cancel"
                    else "best commands at each frequency")
            print(f"  {m:<8} ({what}): {c.reduction_pct:6.1f} % reduction")
    return 0
