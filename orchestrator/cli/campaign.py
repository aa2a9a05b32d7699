"""``jitterfmu campaign``: run a campaign of scenarios and write its jitter summary."""

from __future__ import annotations

import importlib
import json
import os
import sys
from pathlib import Path

COMMAND = "campaign"
HELP = "run a campaign (events x configurations x sweeps) and summarise the jitter"


def add_arguments(parser) -> None:
    """Declare the options of ``jitterfmu campaign``."""
    from ._options import add_fmu_dir, add_out, add_workers

    parser.add_argument("campaign", type=Path, help="campaign TOML file")
    add_out(parser, "<campaign name>", "output folder, reused to resume", type=Path)
    add_workers(parser, "; 0 = in this process; a Monte Carlo of fewer than 40 samples "
                        "runs in this process unless given")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="run on an existing Dask cluster (e.g. tcp://host:8786)")
    parser.add_argument("--runner", default=None, metavar="MODULE:FUNCTION",
                        help="case runner callable(scenario_dict, out_dir) -> results.parquet "
                             "(default: the co-simulation master)")
    add_fmu_dir(parser)
    parser.add_argument("--python-fmus", action="store_const", const="python",
                        dest="fmu_kind", default=None,
                        help="run the Python build of the suite's FMUs (FMU_DIR/python/) "
                             "instead of the native ones")
    parser.add_argument("--engine", choices=("cosim", "linear"), default=None,
                        help="cosim: co-simulate every case (the reference); linear: the "
                             "linear engine, milliseconds a case (default: the campaign "
                             "file's engine, else cosim)")
    parser.add_argument("--verify", type=int, default=None, metavar="N",
                        help="with the linear engine, co-simulate the N cases with the "
                             "largest jitter and report the difference (default: the "
                             "campaign file's verify, else 2)")
    parser.add_argument("--uncertainty", type=Path, default=None, metavar="FILE",
                        help="a TOML file of one [uncertainty] table: the Monte Carlo of the "
                             "campaign under it (replaces the campaign file's table), e.g. "
                             "campaigns/eos_uncertainty.toml")
    parser.add_argument("--samples", type=int, default=None, metavar="N",
                        help="the Monte Carlo's sample count, in place of the table's (a "
                             "larger count in the same --out keeps the samples run before; "
                             "default: the [uncertainty] table's samples)")
    parser.add_argument("--format", choices=("parquet", "csv", "mat"), default="parquet",
                        help="also write the results as CSV or MATLAB files beside the "
                        "Parquet ones: each case's time histories, and with mat the "
                        "summary, budget, cases and Monte Carlo samples in campaign.mat "
                        "(default: %(default)s)")
    parser.add_argument("--quiet", action="store_true",
                        help="no start line and no progress bar or lines")


def _import_runner(spec: str):
    mod, sep, attr = spec.partition(":")
    if not sep or not mod or not attr:
        raise ValueError(f"runner {spec!r} must have the form 'module:function'")
    obj = getattr(importlib.import_module(mod), attr, None)
    if not callable(obj):
        raise ValueError(f"runner {spec!r} is not a callable in module {mod!r}")
    return obj


def _report_wiring(scenario: dict, folder: Path, args, out: Path) -> None:
    """Print the unconnected inputs of the campaign's scenario once for the whole run:
    their count, and their names in ``out/unconnected_inputs.txt``.

    Every case has the same wiring; its workers keep the warning to themselves
    (:func:`orchestrator.cli.show_warning`), so it is printed here, once.
    """
    import warnings

    from .. import load_scenario, prepare
    from ..cosim import UnconnectedInputWarning
    from ..files import write_text_atomic
    from . import UNCONNECTED_NAMES, report_warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            sc = load_scenario(scenario, folder)
            if args.fmu_kind:
                sc = sc.with_experiment(fmu_kind=args.fmu_kind)
            plan = prepare(sc, args.fmu_dir)
        except Exception:  # noqa: BLE001 - a scenario that fails fails in its cases
            return
    if plan.unconnected and (out.is_dir() or not out.exists()):
        names = out / "unconnected_inputs.txt"
        out.mkdir(parents=True, exist_ok=True)
        write_text_atomic(names, "".join(f"{n}\n" for n in plan.unconnected))
        UNCONNECTED_NAMES["where"] = str(names)
    report_warnings([w for w in caught if issubclass(w.category, UnconnectedInputWarning)])


def run(args) -> int:
    # deferred: the parser imports every subcommand (orchestrator.cli)
    import dataclasses

    from ..campaign import (
        CampaignInterrupted,
        LinearRunner,
        MasterRunner,
        check_uncertain_inputs,
        load_campaign,
        run_campaign,
        run_uncertainty,
        run_wheel_sweeps,
        slug,
        verify_campaign,
        write_summary,
    )
    from ..campaign.mcloop import path_lines
    from ..campaign.mcresults import command_lines, convergence_hint
    from ..progress import stage
    from ._options import shown

    camp = load_campaign(args.campaign, args.uncertainty, args.samples)
    engine = args.engine or camp.engine
    if args.verify is not None and args.verify < 0:
        raise ValueError(f"--verify is {args.verify}; expected a number of cases >= 0")
    if args.runner and engine == "linear":
        raise ValueError("--runner and the linear engine exclude each other: the linear "
                         "engine is its own runner")
    if args.runner:
        runner = _import_runner(args.runner)
    elif engine == "linear":
        runner = LinearRunner(camp.scenario_dir, fmu_dir=args.fmu_dir)
    else:
        runner = MasterRunner(camp.scenario_dir, fmu_dir=args.fmu_dir, fmu_kind=args.fmu_kind)
    # the wheel sweeps and the Monte Carlo run on the linear engine (the FMUs of --fmu-dir)
    linear = runner if isinstance(runner, LinearRunner) else LinearRunner(
        camp.scenario_dir, fmu_dir=args.fmu_dir)
    camp = dataclasses.replace(camp, engine=engine)
    if camp.uncertainty:
        check_uncertain_inputs(camp, linear)     # before any case runs, not after them
    out = args.out or Path("out") / slug(camp.name)
    n_workers = 0 if engine == "linear" else (
        args.workers if args.workers is not None else os.cpu_count() or 1)
    where = f"on {args.scheduler}" if args.scheduler else (
        f"{n_workers} worker{'s' * (n_workers != 1)}" if n_workers else "in this process")
    work = [f"{len(camp.cases)} cases"] if camp.cases else []
    work += [f"{len(camp.wheel_sweeps)} wheel sweep{'s' * (len(camp.wheel_sweeps) != 1)}"
             ] if camp.wheel_sweeps else []
    if not args.quiet:
        stage(f"campaign {camp.name!r}: {', '.join(work) or 'nothing to run'} ({engine} "
              f"engine, {where}) into {shown(out)}")
    if camp.cases:   # after the start line: what runs first, then how it is wired
        _report_wiring(camp.cases[0].scenario, camp.scenario_dir, args, out)
    try:
        res = run_campaign(camp, out, runner, workers=args.workers, scheduler=args.scheduler,
                           progress=False if args.quiet else None)
    except CampaignInterrupted as exc:
        print(f"jitterfmu: {exc}", file=sys.stderr)
        return 128 + exc.signum
    for label, why in res.rerun.items():
        print(f"  case {label!r} not trusted ({why}); running it again", file=sys.stderr)
    if res.n_cases:
        print(f"{res.n_cases} cases: {res.n_run} run, {res.n_skipped} already finished, "
              f"{res.n_failed} failed ({engine} engine); cases in {out / 'summary.csv'}, "
              f"budget in {out / 'budget.csv'}")
    for line in budget_lines(out / "summary.parquet"):
        print(line)
    for label, err in res.failures.items():
        print(f"  failed: {label}: {err}", file=sys.stderr)
    n_verify = args.verify if args.verify is not None else camp.verify
    if engine == "linear" and n_verify > 0 and camp.cases:
        from ..campaign import keyed
        camp = keyed(camp, runner)
        if not args.quiet:
            stage(f"verifying the linear engine: co-simulating the {n_verify} case(s) with "
                  "the largest jitter")
        rep = verify_campaign(camp, out, n_verify, fmu_dir=args.fmu_dir,
                              fmu_kind=args.fmu_kind)
        write_summary(camp, out)   # the summary records the cross-check
        print(f"verified {rep['n']} case(s) by co-simulation ({out / 'verify.json'})"
              + (":" if rep["largest_difference"] else ": no case finished to compare"))
        for ia, d in sorted(rep["largest_difference"].items()):
            print(f"  {ia:<16} signal {d['signal']:.2e} of its peak, metric {d['metric']:.2e}")
        for item in rep["nonlinear"]:
            print(f"  NONLINEAR in co-simulation: {item['case']}: {', '.join(item['flags'])}",
                  file=sys.stderr)
        for item in rep["cases"]:
            if "error" in item:
                print(f"  co-simulation failed: {item['case']}: {item['error']}",
                      file=sys.stderr)
    if camp.wheel_sweeps:
        path = run_wheel_sweeps(camp, out, linear,
                                progress=lambda text: print(f"  {text}"))
        print(f"wheel sweeps: {path} (worst speeds in {out / 'wheel_sweeps_worst.csv'})")
        for line in wheel_lines(out / "wheel_sweeps_worst.csv"):
            print(line)
    if camp.uncertainty:
        # from 40 samples on, one worker per CPU (each closes its own loops) unless
        # --workers says otherwise
        many = (camp.uncertainty.get("max_samples") or camp.uncertainty["samples"]) >= 40
        workers = args.workers if args.workers is not None else (
            (os.cpu_count() or 1) if many else 0)
        if not args.quiet:
            stage(f"uncertainty: {camp.uncertainty['samples']} samples "
                  f"({camp.uncertainty['engine']} engine"
                  + (f", up to {camp.uncertainty['max_samples']}"
                     if camp.uncertainty.get("max_samples") else "") + ")")
        try:
            path = run_uncertainty(camp, out, linear,
                                   progress=False if args.quiet else None,
                                   workers=workers, scheduler=args.scheduler)
        except CampaignInterrupted as exc:
            print(f"jitterfmu: {exc}", file=sys.stderr)
            return 128 + exc.signum
        rep = json.loads(path.read_text(encoding="utf-8"))
        resumed = (f", {rep['resumed']} of them kept from an earlier run"
                   if rep.get("resumed") else "")
        print(f"uncertainty: {rep['samples']} samples in {rep['wall_s']:.1f} s{resumed} "
              f"({path}); {rep['interpretation']}")
        for text in path_lines(rep.get("linear_engine") or {}):
            print(text)
        if rep.get("max_samples"):
            steps = " -> ".join(str(r["samples"]) for r in rep["rounds"])
            widest = rep["rounds"][-1]["widest_interval"]
            print(f"  extended until converged: {steps} samples (at most "
                  f"{rep['max_samples']}); " + (
                      "no finite value to converge" if widest is None else
                      f"widest interval of a finite value {100 * widest:.2g} %"
                      + ("" if widest < 0.02 else ": not converged at max_samples")))
        for text in command_lines(rep):
            print(text)
        hint = convergence_hint(rep)
        if hint:
            print(f"  {hint}")
    if args.format != "parquet":
        from ..campaign.export import export_results

        files = export_results(out, args.format)
        print(f"results as {args.format}: {len(files)} file(s)"
              + (f", {out / 'campaign.mat'} and cases/*/results.mat" if args.format == "mat"
                 else ", cases/*/results.csv"))
    return min(res.n_failed, 100)


def wheel_lines(worst_csv, limit: int = 20) -> list:
    """The worst wheel speed of each instrument axis, per configuration, as lines.

    Parameters
    ----------
    worst_csv : path-like
        The campaign's ``wheel_sweeps_worst.csv``.
    limit : int
        Instrument-axis lines at most (the rest are counted).

    Returns
    -------
    list of str
        Empty when the file is missing or empty.
    """
    import csv

    try:
        with open(worst_csv, newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
    except OSError:
        return []
    lines: dict = {}
    for r in rows:
        lines.setdefault((r["sweep"], r["instrument"], r["axis"]), []).append(r)
    if not lines:
        return []
    first = rows[0]
    out = [f"worst wheel speed per axis ({first['metric']} over {float(first['window']):g} s, "
           f"{first['unit']}; requirement in brackets):"]
    for (sweep, inst, axis), rs in list(lines.items())[:limit]:
        req = rs[0]["requirement"]
        cells = [f"{r['configuration']} {float(r['value']):.3g} at "
                 f"{float(r['worst_rpm']):.0f} rpm" for r in rs]
        out.append(f"  {inst} {axis}: " + " | ".join(cells)
                   + (f"  [{float(req):.3g}]" if req not in ("", "nan") else ""))
    if len(lines) > limit:
        out.append(f"  ... {len(lines) - limit} more lines in {worst_csv}")
    return out


def budget_lines(summary_path, limit: int = 20) -> list:
    """The verdict a user runs a campaign for, as lines to print.

    Per instrument and axis, the RSS of each configuration against its requirement, for
    the first metric that has requirements; with sweeps, each configuration's worst
    sweep point, named.  The values are the report's verdict table
    (:func:`orchestrator.report_verdict.verdicts`), so terminal and report agree.

    Parameters
    ----------
    summary_path : path-like
        The campaign's ``summary.parquet``.
    limit : int
        Instrument-axis lines at most (the rest are counted).

    Returns
    -------
    list of str
        Empty when no summary or no requirement.
    """
    import math

    from ..campaign.spec import RSS_EVENT
    from ..report_verdict import verdicts, with_units
    from ..results import read_parquet

    try:
        rows = read_parquet(summary_path).to_pylist()
    except OSError:
        return []
    try:   # the swept parameters' units, beside the summary
        units = json.loads((Path(summary_path).parent / "campaign.json").read_text(
            encoding="utf-8")).get("sweep_units") or {}
    except (OSError, ValueError):
        units = {}
    first = next((r for r in rows if r["event"] == RSS_EVENT
                  and r["requirement"] == r["requirement"]), None)   # not NaN
    if first is None:
        return []
    metric, window = first["metric"], first["window"]
    configs, axes = verdicts(rows, metric, window)
    axes = with_units([v for v in axes if not math.isnan(v.requirement)], units)
    swept = any(any(v.sweep) for v in axes)
    what = f"{metric} over {window:g} s" if window == window else metric
    out = [f"budget ({what}, RSS over events, {first['unit']}"
           + ("; the worst sweep point of each configuration" if swept else "") + "):"]
    words = {True: "PASS", False: "FAIL", "incomplete": "incomplete"}
    for v in axes[:limit]:
        cells = [f"{cf or 'all'} {value:.3g} ({words.get(ok, 'n/a')})"
                 + (f" at {point}" if point else "")
                 for cf, value, ok, point in zip(configs, v.rss, v.passed, v.sweep)]
        out.append(f"  {v.instrument} {v.axis}: " + " | ".join(cells)
                   + f"  requirement {v.requirement:.3g}")
    if len(axes) > limit:
        out.append(f"  ... {len(axes) - limit} more lines in budget.csv")
    return out
