"""``jitterfmu reproduce NAME --out DIR``: run one of the paper's experiments."""

from __future__ import annotations

COMMAND = "reproduce"
HELP = "reproduce one of the paper's experiments (writes DIR/NAME.json and figures)"


def add_arguments(parser):
    """Declare the options of ``jitterfmu reproduce``."""
    # deferred: the parser imports every subcommand (orchestrator.cli)
    from orchestrator.experiments import EXPERIMENTS

    from ._options import add_fmu_dir, add_out, add_workers

    parser.add_argument("name", help=f"experiment: {', '.join(EXPERIMENTS)}")
    add_out(parser, "<experiment name>", "output folder for NAME.json and the figures")
    parser.add_argument("--quick", action="store_true",
                        help="shorter runs (what the tests use)")
    add_fmu_dir(parser, builds=True)
    add_workers(parser, "; eos-budget's campaign")
    parser.add_argument("--campaign", default=None,
                        help="campaign file whose [[requirements]] the budget uses "
                             "(eos-budget; default: campaigns/eos_budget.toml)")
    parser.add_argument("--python-fmus", action="store_const", const="python",
                        dest="fmu_kind", default=None,
                        help="run the Python build of the suite's FMUs (FMU_DIR/python/) "
                             "instead of the native ones")
    parser.add_argument("--variant", default=None,
                        choices=("stiff", "hybrid", "decentralized", "central"),
                        help="testbed-isolation: mount #3 as the paper describes it (stiff, "
                             "default) or the hybrid isolator (stack + elastomer); "
                             "swir-isolation: the paper's law on each leg (decentralized, "
                             "default) or one controller on all twelve strains (central)")
    parser.add_argument("--servo-hz", type=float, default=None, dest="servo_hz",
                        help="testbed-servo: crossover of the MISR stacks' built-in servo "
                             "loops (Hz; default 100, assumed)")
    parser.add_argument("--design", action="store_const", const=True, default=None,
                        help="testbed-robust: also design mount #3's law within the "
                             "paper's structure at each pair of corners (about 15 min)")


def run(args) -> int:
    """Run the experiment, print its main numbers; 0, or 1 if a campaign case failed."""
    # deferred: the parser imports every subcommand (orchestrator.cli)
    import importlib

    from orchestrator.experiments import EXPERIMENTS, _clean
    from orchestrator.experiments import run as run_experiment

    import time

    from orchestrator.progress import stage

    from ._options import cpu_workers, shown

    workers = args.workers
    if workers is None and args.name == "eos-budget":
        workers = cpu_workers()
    options = {k: v for k, v in (("workers", workers), ("campaign", args.campaign),
                                 ("variant", args.variant), ("fmu_kind", args.fmu_kind),
                                 ("servo_hz", args.servo_hz), ("design", args.design))
               if v is not None}
    out = args.out or f"out/{args.name}"
    t0 = time.monotonic()
    stage(f"reproduce {args.name} ({'quick' if args.quick else 'full length'}): FMUs in "
          f"{shown(args.fmu_dir or 'fmus')} (built if missing or stale), results into "
          f"{shown(out)}")
    result = run_experiment(args.name, out, quick=args.quick, fmu_dir=args.fmu_dir,
                            **options)
    stage(f"reproduce {args.name}: done in {time.monotonic() - t0:.0f} s")
    module = importlib.import_module(EXPERIMENTS[args.name])
    if hasattr(module, "summary"):
        print(module.summary(result))
    else:
        for line in verdict_lines(result):
            print(line)
        shown = {k: v for k, v in result.items() if k not in ("note", "verdict") and (
                 not isinstance(v, (list, dict)) or
                 k in ("jitter_reduction_pct", "reduction_pct", "jitter_off_arcsec",
                       "rigid_body_share_pct", "open_loop_damping",
                       "closed_loop_cycles_to_90pct", "modes_hz"))}
        for line in number_lines(_clean(shown)):
            print(line)
    print(f"wrote {out}/{args.name}.json")
    return 1 if result.get("n_failed") else 0


def number_lines(numbers: dict) -> list:
    """An experiment's main numbers as ``  name: value`` lines (4 significant digits).

    Parameters
    ----------
    numbers : dict
        Names to numbers, strings, lists of numbers or dicts of them (one level).
    """
    def fmt(v):
        if isinstance(v, float):
            return f"{v:.4g}"
        if isinstance(v, list):
            return ", ".join(fmt(x) for x in v)
        if isinstance(v, dict):
            return "; ".join(f"{k} {fmt(x)}" for k, x in v.items())
        return str(v)
    return [f"  {k}: {fmt(v)}" for k, v in numbers.items()]


def verdict_lines(result: dict) -> list:
    """What a user runs an experiment for, first: one line per paper target (ours, the
    paper's words, reproduced / beats the paper / missed), the experiment's verdict, and
    its bounds, the true upper bound first, each named for what it bounds.

    Parameters
    ----------
    result : dict
        An experiment's result (its JSON), with ``verdicts`` and optionally ``bounds``.
    """
    from orchestrator.experiments import verdicts as vd

    lines = []
    for v in result.get("verdicts", ()):
        lines.append("  " + vd.outcome_words(v))
    if "verdicts" in result:
        lines.insert(0, f"verdict: {vd.overall(result['verdicts'])}")
    for b in result.get("bounds", ()):
        vals = ", ".join(f"{k} {x:.1f} %" for k, x in b["pct"].items() if x is not None)
        lines.append(f"{b['name']}: {vals} ({'bounds ' if b['is_bound'] else ''}"
                     f"{b['bounds']})")
    return lines
