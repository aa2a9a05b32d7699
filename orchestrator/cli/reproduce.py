"""``jitterfmu reproduce NAME --out DIR``: run one of the paper's experiments."""

from __future__ import annotations

COMMAND = "reproduce"
HELP = "reproduce one of the paper's experiments (writes DIR/NAME.json and figures)"


def add_arguments(parser):
    from orchestrator.experiments import EXPERIMENTS

    parser.add_argument("name", help=f"experiment: {', '.join(EXPERIMENTS)}")
    parser.add_argument("--out", default="out", help="output folder (default: out)")
    parser.add_argument("--quick", action="store_true",
                        help="shorter runs (what the tests use)")
    parser.add_argument("--fmu-dir", default=None,
                        help="folder to build the FMUs into (experiments that take one)")


def run(args) -> int:
    import json

    from orchestrator.experiments import run as run_experiment

    result = run_experiment(args.name, args.out, quick=args.quick, fmu_dir=args.fmu_dir)
    shown = {k: v for k, v in result.items() if not isinstance(v, (list, dict)) or
             k in ("jitter_reduction_pct", "reduction_pct", "jitter_off_arcsec",
                   "ideal_ceiling_pct", "rigid_body_share_pct", "open_loop_damping",
                   "closed_loop_cycles_to_90pct")}
    from orchestrator.experiments import _clean
    print(json.dumps(_clean(shown), indent=2))
    print(f"wrote {args.out}/{args.name}.json")
    return 0
