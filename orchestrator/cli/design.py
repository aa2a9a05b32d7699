"""``jitterfmu design``: the ACS on the flexible plant, and a robust design of the gains."""

from __future__ import annotations

COMMAND = "design"
HELP = ("design the ACS on the flexible plant and tune controller gains for a campaign's "
        "jitter, stable with stated margins over an uncertainty set")


def add_arguments(parser) -> None:
    """Declare the options of ``jitterfmu design``."""
    from ._options import add_fmu_dir, add_out

    parser.add_argument("scenario", help="scenario file (.toml)")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="INST.VAR=VALUE", help="set a start value (repeatable)")
    add_fmu_dir(parser)
    parser.add_argument("--tune", action="append", default=[], metavar="LIST",
                        help="what to tune, comma separated (repeatable): 'acs', a "
                             "controller (ctrl_iso1 or ctrl_iso1.gain: its own factor), a "
                             "family (ctrl_iso or ctrl_iso*: one common factor)")
    parser.add_argument("--campaign", default=None, metavar="C.toml",
                        help="the objective: the jitter of this campaign's lines under its "
                             "events (its base scenario and configurations are replaced by "
                             "SCENARIO with --set)")
    parser.add_argument("--uncertainty", default=None, metavar="U.toml",
                        help="the set every candidate must be stable over (its "
                             "[uncertainty] table)")
    parser.add_argument("--samples", type=int, default=20, metavar="N",
                        help="random points of the set judging each candidate (default 20)")
    parser.add_argument("--seed", type=int, default=None,
                        help="seed of those points (default the file's); the independent "
                             "check uses seed + 1")
    parser.add_argument("--grid", type=int, default=3,
                        help="common frequency factors of the damping corners (default 3)")
    parser.add_argument("--set-scale", type=float, default=1.0, metavar="K",
                        help="judge each point of the set at K times its distance from "
                             "nominal (default 1)")
    parser.add_argument("--margin-db", type=float, default=6.0,
                        help="gain margin of each tuned loop and of a gain-stabilised mode "
                             "(dB, default 6)")
    parser.add_argument("--phase-margin", type=float, default=30.0,
                        help="ACS rigid-body and phase-stabilised margin (deg, default 30)")
    parser.add_argument("--disk-margin-db", type=float, default=0.0,
                        help="ACS MIMO disk margin required (dB, default 0: reported only)")
    parser.add_argument("--gain-stabilise", action="store_true",
                        help="ACS: every flexible mode above crossover gain-stabilised "
                             "(no phase stabilisation)")
    parser.add_argument("--bandwidths", type=float, nargs=2, default=(0.1, 0.01),
                        metavar=("HIGH", "LOW"), help="ACS crossovers searched (Hz)")
    parser.add_argument("--steps", type=int, default=21,
                        help="ACS crossovers in that range, log spaced (default 21)")
    parser.add_argument("--max-evaluations", type=int, default=80,
                        help="most candidates of the gain search (default 80)")
    add_out(parser, "<scenario file name without .toml>-design",
            "folder for design.json, set.txt and scenario.toml")


def run(args) -> int:
    """Design, print the result, write the files; return 0."""
    import math
    import tomllib
    from pathlib import Path

    from orchestrator.analysis import AnalysisError, linearize
    from orchestrator.analysis.robustdesign import robust_design, tune_targets
    from orchestrator.campaign.spec_base import CampaignError
    from orchestrator.campaign.spec_uncertainty import parse_uncertainty
    from orchestrator.progress import stage
    from orchestrator.scenario import parse_override

    overrides = dict(parse_override(s) for s in args.overrides)
    tune = [t for item in args.tune for t in item.split(",") if t.strip()]
    if not tune:
        raise AnalysisError("--tune is missing: name what to design (acs, controllers or "
                            "families), e.g. --tune acs,ctrl_iso")
    if not (math.isfinite(args.margin_db) and args.margin_db >= 0):
        raise AnalysisError(f"the requested gain margin {args.margin_db:g} dB is below 0 dB; "
                            "expected 0 dB or more (6 dB is usual)")
    if not args.campaign and any(t.strip() != "acs" for t in tune):
        raise AnalysisError("tuning gains needs an objective: give a campaign whose events "
                            "and instruments define the jitter to lower (--campaign)")
    if "acs" in tune:
        from acsfmu.flexible import check_margins

        check_margins(phase_margin=args.phase_margin, gain_margin_db=args.margin_db,
                      disk_margin_db=args.disk_margin_db)
    items, seed = None, args.seed
    if args.uncertainty:
        try:
            with open(args.uncertainty, "rb") as fh:
                table = tomllib.load(fh).get("uncertainty")
        except (OSError, tomllib.TOMLDecodeError) as exc:
            raise CampaignError(f"cannot read the uncertainty file {args.uncertainty}: "
                                f"{exc}") from None
        if table is None:
            raise CampaignError(f"{args.uncertainty} has no [uncertainty] table")
    objective = None
    if args.campaign:
        from orchestrator.campaign.objective import CampaignObjective

        stage(f"design: the objective from {args.campaign} on {args.scenario}")
        objective = CampaignObjective(args.campaign, args.scenario, overrides, args.fmu_dir)
        lin = objective.lin
    else:
        lin = linearize(args.scenario, overrides=overrides, fmu_dir=args.fmu_dir)
    tune_targets(lin, tune)           # refused in one sentence before any design work
    if args.uncertainty:
        spec = parse_uncertainty(table, {n: None for n in lin.blocks})
        items = spec["parameters"]
        seed = spec["seed"] if seed is None else seed
    acs_options = {"phase_margin": args.phase_margin, "gain_margin_db": args.margin_db,
                   "disk_margin_db": args.disk_margin_db, "bandwidths": tuple(args.bandwidths),
                   "steps": args.steps, "phase_stabilise": not args.gain_stabilise}
    res = robust_design(lin, items, tune, objective, margin_db=args.margin_db,
                        samples=args.samples, seed=seed or 0, grid=args.grid,
                        set_scale=args.set_scale, acs_options=acs_options,
                        max_evaluations=args.max_evaluations,
                        progress=lambda m: stage(f"design: {m}"))
    print(text(res))
    out = Path(args.out) if args.out else Path("out") / f"{Path(args.scenario).stem}-design"
    write(res, out, args.scenario, {**overrides, **res.overrides}, args.fmu_dir)
    print(f"\nwritten: {out / 'design.json'}, {out / 'set.txt'}, {out / 'scenario.toml'}")
    return 0


def text(res) -> str:
    """The design as lines: ACS per axis, factors, objective, margins, robust check."""
    from orchestrator.analysis.loops import disk_to_gain_phase

    lines = []
    if res.acs is not None:
        d = res.acs.design
        lines.append(f"ACS on the flexible plant ({res.acs.seconds:.1f} s):")
        lines.append(f"  {'axis':<6} {'design':<72} {'PM deg':>7} {'worst mode':>26}")
        req = d.searched
        for a in d.axes:
            w = a.worst_mode(req.get("gain_margin_db", 6.0), req.get("phase_margin_deg", 30.0))
            ws = (f"{w.freq_hz:.3g} Hz {w.how} {w.margin:.1f} {w.unit}" if w else "none")
            lines.append(f"  {a.axis:<6} {a.choice.describe():<72} {a.phase_margin:7.1f} "
                         f"{ws:>26}")
        lines.append(f"  MIMO disk margin {d.disk_db:.2f} dB / {d.disk_deg:.1f} deg")
    if res.factors:
        lines.append("gains (factor on the start):")
        for label, f in res.factors.items():
            lines.append(f"  {label:<16} x{f:.4g}")
    if res.objective is not None:
        o0 = res.objective_start
        lines.append(f"objective: {res.searched.get('objective')}")
        lines.append(f"  start {o0.value:.4g}{' (' + o0.binding + ')' if o0.binding else ''}"
                     f"{'' if res.start_feasible else ', not feasible: ' + res.start_reason}")
        lines.append(f"  design {res.objective.value:.4g}"
                     f"{' (' + res.objective.binding + ')' if res.objective.binding else ''}"
                     f", {res.searched['evaluations']} candidates judged")
    lines.append(f"margins of the designed loop (stable: "
                 f"{'yes' if res.lin.is_stable() else 'NO'}):")
    for g in res.margins:
        gd, pd = disk_to_gain_phase(g.disk_alpha)
        for m in g.loops:
            lines.append(f"  {m.loop:<22} gain up {m.gain_up_db:.1f} dB, down "
                         f"{m.gain_down_db:.1f} dB, phase {m.phase_deg:.1f} deg, disk "
                         f"{m.disk_db:.1f} dB")
        lines.append(f"  {g.name:<22} MIMO disk {gd:.2f} dB / {pd:.1f} deg")
    for what, r in (("judged", res.robust), ("independent", res.resample)):
        if r is None:
            continue
        bad = sum(not c["stable"] for c in r["corners"])
        mf = r["margin_found"]
        lines.append(f"robust ({what} draw): {r['unstable']} of {r['samples']} samples "
                     f"unstable, {len(r['corners']) - bad} of {len(r['corners'])} corners "
                     f"stable, worst |z| {r['worst_abs_z']:.6f}"
                     + (f", destabilising scale found {mf:.3g}" if what == "judged" and mf
                        else ""))
    lines.append(f"time {res.seconds:.1f} s")
    return "\n".join(lines)


def write(res, out, scenario, overrides, fmu_dir=None) -> None:
    """Write ``design.json``, ``set.txt`` and ``scenario.toml`` into a folder.

    Parameters
    ----------
    res : RobustDesign
        The design.
    out : Path
        Folder (created).
    scenario : path-like
        The scenario designed.
    overrides : dict of str to value
        Its start values and the design's (written as ``--set`` lines and into the
        scenario, whose FMUs are given by absolute path).
    fmu_dir : path-like, optional
        Folder searched first for FMUs.
    """
    import json
    import math
    import tomllib
    from pathlib import Path

    import tomli_w

    from orchestrator.cosim import find_fmu
    from orchestrator.files import write_text_atomic
    from orchestrator.scenario import load_scenario

    out.mkdir(parents=True, exist_ok=True)

    def clean(v):
        if isinstance(v, float) and not math.isfinite(v):
            return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        return v
    data = {"scenario": str(scenario), "set": {k: v for k, v in overrides.items()},
            **res.as_dict()}
    write_text_atomic(out / "design.json", json.dumps(clean(data), indent=1, default=float))
    write_text_atomic(out / "set.txt", "".join(f"--set {k}={v!r}\n"
                                               for k, v in overrides.items()))
    with open(scenario, "rb") as fh:
        doc = tomllib.load(fh)
    sc = load_scenario(scenario)
    for name, spec in doc.get("fmus", {}).items():
        inst = next(i for i in sc.instances if i.name == name)
        spec["fmu"] = str(Path(find_fmu(inst.fmu, sc, fmu_dir)).resolve())
    for key, value in overrides.items():
        inst, var = key.split(".", 1)
        doc["fmus"][inst].setdefault("parameters", {})[var] = value
    write_text_atomic(out / "scenario.toml",
                      f"# {scenario} with the design of jitterfmu design (design.json)\n"
                      + tomli_w.dumps(doc))
