"""``jitterfmu analyze``: the linear closed loop of a scenario, before tuning it."""

from __future__ import annotations

import sys

COMMAND = "analyze"
HELP = ("linear closed loop of a scenario: poles and damping, decay of a mode, gain "
        "margins per loop, upper bound on reducing a performance output")


def add_arguments(parser) -> None:
    """Declare the options of ``jitterfmu analyze``."""
    from ._options import add_fmu_dir, add_stop

    parser.add_argument("scenario", help="scenario file (.toml) or SSP archive (.ssp)")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="INST.VAR=VALUE", help="set a start value (repeatable)")
    parser.add_argument("--period", dest="periods", action="append", default=[],
                        metavar="INST=SECONDS",
                        help="step an instance every SECONDS instead of its scenario "
                             "period (repeatable; a piezo with coupling 1 also needs "
                             "--set INST.hold_step=SECONDS)")
    add_fmu_dir(parser)
    parser.add_argument("--open", action="append", default=[], metavar="INST",
                        help="take an instance out of the loop (its outputs held at zero), "
                             "e.g. a slow ACS whose period hides faster poles (repeatable)")
    parser.add_argument("--mode", type=float, action="append", default=[], metavar="HZ",
                        help="report the decay of the pole nearest this mode (repeatable)")
    parser.add_argument("--band", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                        help="list the closed-loop poles in this band (Hz)")
    parser.add_argument("--no-margins", action="store_true", help="skip the loop margins")
    parser.add_argument("--uncertainty", default=None, metavar="U.toml",
                        help="robust stability over the [uncertainty] set of this file: "
                             "sampled points, damping corners, the smallest destabilising "
                             "scale of the set found")
    parser.add_argument("--samples", type=int, default=None, metavar="N",
                        help="with --uncertainty: random points (default the file's "
                             "samples, at most 200)")
    parser.add_argument("--json", default=None, metavar="FILE.json",
                        help="write the poles' stability and every loop's margins to FILE")
    parser.add_argument("--performance", action="append", default=[], metavar="INST.VAR",
                        help="output whose upper bound on reduction to compute "
                             "(repeatable)")
    parser.add_argument("--disturbance", default=None, metavar="INST.VAR",
                        help="source output carrying the disturbance (for the bound)")
    parser.add_argument("--freq", type=float, action="append", default=[], metavar="HZ",
                        help="disturbance line (Hz, repeatable)")
    parser.add_argument("--actuator", action="append", default=[], metavar="CONTROLLER",
                        help="controller instance whose command is free in the bound "
                             "(repeatable; default: every controller)")
    parser.add_argument("--method", choices=["optimal", "cancel", "both"], default="both",
                        help="optimal: the upper bound (best commands at each line); "
                             "cancel: the controllers' sensors held at zero (infinite "
                             "gain, a reference point, not a bound)")
    parser.add_argument("--reference", action="store_true",
                        help="compare with the sampled-data reference (continuous structure "
                             "and amplifiers, the controllers at their rates): what the "
                             "partition adds to each loop at its crossover, and the "
                             "co-simulated outputs against it")
    add_stop(parser, lead="with --reference: ")
    parser.add_argument("--output", action="append", default=[], metavar="INST.VAR",
                        help="with --reference or --transfer: output to compare or to "
                             "reach (repeatable; default the scenario's [record])")
    parser.add_argument("--transfer", action="append", default=[], metavar="INST.VAR",
                        help="closed-loop transfer from this source output to each "
                             "--output (repeatable; a frequency grid from --fmin to --fmax)")
    parser.add_argument("--fmin", type=float, default=0.1, help="lowest frequency (Hz)")
    parser.add_argument("--fmax", type=float, default=None,
                        help="highest frequency (Hz; default 0.45 x the base rate)")
    parser.add_argument("--points", type=int, default=400, help="frequencies (log spaced)")
    parser.add_argument("--psd", type=float, default=None, metavar="LEVEL",
                        help="with --transfer: one random signal of this one-sided PSD "
                             "((input unit)^2/Hz, white in --psd-band) on the --transfer "
                             "inputs together: output PSD and cumulative RMS")
    parser.add_argument("--psd-band", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                        help="band of the --psd signal (Hz; default the whole grid)")
    parser.add_argument("--plot", default=None, metavar="FILE.png",
                        help="with --transfer: draw the transfers (and PSD) to this file")
    parser.add_argument("--csv", default=None, metavar="FILE.csv",
                        help="with --transfer: write the frequency table to this file")


def run(args) -> int:
    """Print the analysis; return 0."""
    # deferred: the parser imports every subcommand (orchestrator.cli)
    from orchestrator.analysis import AnalysisError, ceiling, linearize, report
    from orchestrator.analysis.loops import scenario_margins
    from orchestrator.scenario import parse_override

    from orchestrator.progress import stage

    overrides = dict(parse_override(s) for s in args.overrides)
    from ._options import shown

    scenario = _with_periods(args.scenario, args.periods) if args.periods else args.scenario

    stage(f"analyze {shown(args.scenario)}: linearising the closed loop"
          + (" and co-simulating it" if args.reference else ""))
    if args.reference:
        from orchestrator import reference

        res = reference.check(scenario, args.output or None, stop_time=args.stop,
                              overrides=overrides, fmu_dir=args.fmu_dir, opened=args.open)
        print(reference.report(res))
        return 0
    lin = linearize(scenario, overrides=overrides, fmu_dir=args.fmu_dir)
    if args.open:
        lin = lin.opened(args.open)
    if args.transfer:
        return _spectra(lin, args)
    if args.uncertainty:
        stage(f"analyze {shown(args.scenario)}: robust stability over the uncertainty set")
    robust = _robust(lin, args) if args.uncertainty else None
    if not args.no_margins:
        stage(f"analyze {shown(args.scenario)}: the margins of every loop")
    groups = [] if args.no_margins else scenario_margins(lin)
    print(report(lin, modes=args.mode, margins=groups if groups else not args.no_margins,
                 band=args.band))
    if args.json:
        _write_json(args.json, {"scenario": str(args.scenario), "stable": lin.is_stable(),
                                "max_abs_z": max(abs(p.z) for p in lin.poles()),
                                "groups": [g.as_dict() for g in groups],
                                **({"robust": robust} if robust else {})})
    if args.performance:
        if not (args.disturbance and args.freq):
            raise AnalysisError("--performance needs --disturbance INST.VAR and at least "
                                "one --freq HZ")
        actuators = args.actuator or lin.controllers()
        methods = ("optimal", "cancel") if args.method == "both" else (args.method,)
        print()
        print(f"reduction of {', '.join(args.performance)} under {args.disturbance} "
              f"at {', '.join(f'{f:g}' for f in args.freq)} Hz, actuators "
              f"{', '.join(actuators)}")
        for m in methods:
            c = ceiling(lin, args.performance, args.disturbance, args.freq,
                        actuators=actuators, method=m)
            what = ("upper bound: the best commands at each line; no controller at these "
                    "actuators removes more in steady state" if m == "optimal" else
                    "the controllers' sensors held at zero: infinite gain, a reference "
                    "point, not a bound")
            print(f"  {c.reduction_pct:6.1f} %  {what}")
    return 0


def _with_periods(path, items):
    """The scenario at ``path`` with ``--period INST=SECONDS`` applied."""
    from orchestrator.scenario import ScenarioError, load_scenario

    periods = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.strip() or not value.strip():
            raise ScenarioError(f"--period {item!r} is not INST=SECONDS; e.g. "
                                "--period structure=0.0005")
        periods[name.strip()] = value.strip()
    return load_scenario(path).with_periods(periods)


def _spectra(lin, args) -> int:
    """``--transfer``: the closed-loop transfers, and with ``--psd`` the output PSDs."""
    from pathlib import Path

    import numpy as np

    from orchestrator.analysis import AnalysisError
    from orchestrator.analysis.fast import FastResponse
    from orchestrator.analysis.spectra import cumulative_rms, output_psd, transfer

    outputs = args.output or list(lin.plan.scenario.record)
    if not outputs:
        raise AnalysisError("--transfer needs --output INST.VAR (the scenario records none)")
    fmax = args.fmax or 0.45 / lin.base
    if not 0 < args.fmin < fmax or args.points < 2:
        raise AnalysisError(f"the grid {args.fmin:g} to {fmax:g} Hz with {args.points} "
                            "points is empty; expected 0 < --fmin < --fmax and --points >= 2")
    freqs = np.geomspace(args.fmin, fmax, args.points)
    fr = FastResponse(lin, outputs)
    tr = transfer(fr, args.transfer, outputs, freqs)
    print(f"closed-loop transfer, {freqs.size} frequencies {args.fmin:g}-{fmax:g} Hz "
          "(fundamental of the steady state; 'aliased' = the rest, relative)")
    print(f"  {'from':<22} {'to':<28} {'peak |H|':>11} {'at Hz':>9} {'aliased':>8}")
    for i, o in enumerate(outputs):
        for j, src in enumerate(args.transfer):
            mag = np.abs(tr.H[i, j])
            k = int(np.argmax(mag))
            print(f"  {src:<22} {o:<28} {mag[k]:11.4g} {freqs[k]:9.4g} "
                  f"{np.max(tr.aliased[i, j]):8.1e}")
    psd = cum = None
    if args.psd is not None:
        lo, hi = args.psd_band or (freqs[0], freqs[-1])
        level = np.where((freqs >= lo) & (freqs <= hi), args.psd, 0.0)
        psd = output_psd(tr, level)
        cum = cumulative_rms(freqs, psd)
        print(f"random signal {args.psd:g} /Hz in {lo:g}-{hi:g} Hz on "
              f"{', '.join(args.transfer)} together: RMS of each output")
        for i, o in enumerate(outputs):
            half = freqs[int(np.searchsorted(cum[i], cum[i, -1] / np.sqrt(2)))]
            print(f"  {o:<28} {cum[i, -1]:11.4g}  (half the variance below {half:.4g} Hz)")
    if args.csv:
        import csv
        with open(args.csv, "w", newline="", encoding="utf-8") as f:
            w = csv.writer(f)
            head = ["freq_hz"] + [f"|H| {s} -> {o}" for o in outputs for s in args.transfer]
            if psd is not None:
                head += [f"psd {o}" for o in outputs] + [f"cumulative rms {o}" for o in outputs]
            w.writerow(head)
            for k, fk in enumerate(freqs):
                row = [repr(float(fk))] + [repr(float(abs(tr.H[i, j, k])))
                                           for i in range(len(outputs))
                                           for j in range(len(args.transfer))]
                if psd is not None:
                    row += [repr(float(v)) for v in psd[:, k]]
                    row += [repr(float(v)) for v in cum[:, k]]
                w.writerow(row)
        print(f"table: {args.csv}")
    if args.plot:
        from orchestrator.files import atomic_write
        from orchestrator.report import png_bytes
        from orchestrator.report_sweeps import plan_units, transfer_figure
        units = plan_units(lin.plan, [*args.transfer, *outputs])   # as the FMUs declare
        data = png_bytes(transfer_figure(tr, psd, cum, units))
        atomic_write(args.plot, lambda tmp: Path(tmp).write_bytes(data))
        print(f"figure: {args.plot}")
    return 0


def _write_json(path, data) -> None:
    """Write ``data`` as JSON (infinite numbers as the strings "inf"/"-inf")."""
    import json
    import math

    from orchestrator.files import write_text_atomic

    def clean(v):
        if isinstance(v, float) and not math.isfinite(v):
            return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        return v
    write_text_atomic(path, json.dumps(clean(data), indent=1))


def _robust(lin, args) -> dict:
    """``--uncertainty``: the robust-stability answer, printed; the set is checked first."""
    import tomllib

    from orchestrator.analysis.robust import robust_stability, uncertain_set
    from orchestrator.campaign.spec_base import CampaignError
    from orchestrator.campaign.spec_uncertainty import parse_uncertainty
    from orchestrator.progress import ProgressBar

    try:
        with open(args.uncertainty, "rb") as fh:
            table = tomllib.load(fh).get("uncertainty")
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise CampaignError(f"cannot read the uncertainty file {args.uncertainty}: {exc}") \
            from None
    if table is None:
        raise CampaignError(f"{args.uncertainty} has no [uncertainty] table")
    spec = parse_uncertainty(table, {n: None for n in lin.blocks})
    uncertain_set(lin, spec["parameters"])    # refused in one sentence before any work
    n = args.samples if args.samples is not None else min(int(spec["samples"]), 200)
    bar = ProgressBar(1.0, "robust stability")
    try:
        res = robust_stability(lin, spec["parameters"], samples=n, seed=spec["seed"],
                               progress=lambda d, t: bar(d / t),
                               say=lambda text: print(f"  {text}", file=sys.stderr,
                                                      flush=True))
    finally:
        bar.close()
    print(_robust_text(res))
    print()
    return res


def _robust_text(res) -> str:
    """The robust-stability answer as lines."""
    lines = [f"robust stability over {', '.join(res['parameters'])} "
             f"(structure {res['structure']})",
             f"  nominal: max |z| {res['nominal_abs_z']:.6f} "
             f"({'stable' if res['nominal_stable'] else 'UNSTABLE'})",
             f"  sampled: {res['unstable']} of {res['samples']} unstable, P(unstable) <= "
             f"{100 * res['unstable_p_upper']:.2g} % at 95 % (Clopper-Pearson), worst |z| "
             f"{res['worst_abs_z']:.6f}"]
    bad = [c for c in res["corners"] if not c["stable"]]
    lines.append(f"  corners: {len(res['corners']) - len(bad)} of {len(res['corners'])} "
                 "stable (every damping bound x a grid of common frequency factors)")
    for c in bad:
        lines.append(f"    unstable: frequency x{c['frequency_factor']:.3f}, damping "
                     f"{c['damping']} bound, |z| {c['abs_z']:.6f}")
    for d in res["drivers"]:
        modes = ", ".join(f"mode {m['mode']} ({m['nominal_hz']:.3g} Hz, {100 * m['share']:.0f} %)"
                          for m in d["modes"])
        lines.append(f"    sample {d['sample']}: pole |z| {d['abs_z']:.5f} at "
                     f"{d['pole_freq_hz']:.3g} Hz (over the loop period); opening "
                     f"{', '.join(d['loops']) or 'no single loop group'} stabilises it; "
                     f"modes {modes}")
    mf = res["margin_found"]
    lines.append(f"  margin found: {'none up to the search limit' if mf is None else f'{mf:.3g}'}"
                 " (smallest scale of the set about nominal with a destabilising point, "
                 "confirmed by eigenvalues)")
    mg = res["margin_guaranteed"]
    if mg is None:
        lines.append(f"  margin guaranteed: none; {res['certificate']}")
    else:
        det = res.get("certificate_detail", {})
        lines.append(f"  margin guaranteed: {mg:.4g} ({'the whole set' if mg >= 1 else 'NOT the whole set'}"
                     f" proven stable; covers {det.get('covers', '?')}; "
                     f"{det.get('frequencies', '?')} frequencies"
                     + (f", tightest at {det['worst_hz']:.4g} Hz" if det.get("worst_hz") else "")
                     + ")")
        if res.get("margin_gap") is not None:
            lines.append(f"  the true margin lies in [{mg:.4g}, {mf:.4g}] (gap "
                         f"{res['margin_gap']:.3g})")
    return "\n".join(lines)
