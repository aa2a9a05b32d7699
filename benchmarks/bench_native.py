"""Native (C99) FMUs beside their Python twins: same scenarios, same master, one run.

Builds both builds of the FMUs the scenarios use into a temporary folder
(``fmutools.ensure.ensure_fmus``: native FMUs in it, Python twins in its ``python/``),
then compares them side by side:

* end to end: each scenario run with each build in a fresh Python process
  (``run_scenario(..., fmu_kind=...)``), so the wall time includes everything a user
  waits for: process start, imports, loading the FMUs (the Python FMUs import numpy and
  scipy inside), initialisation, the steps and writing the results.  The child also
  times its ``Simulation.initialize`` and ``Simulation.run``, which splits the wall
  time into start-up and steps.  Cases: the ten-bay closed loop
  (``scenarios/truss10_closed_loop.toml``, 12 s, six FMUs) and, with ``--eos``, one EOS
  budget case (``scenarios/eos_budget.toml``, 21 instances, SWIR cryocooler on,
  isolation on) over each ``--eos-stop``;
* with ``--ssp``: the ten-bay closed loop exported as SSP (Jacobi, once per build), run
  by our master and by libcosim (libcosimpy, in a child process), stepping time only;
* with ``--campaign``: the 24 cases of ``campaigns/eos_budget.toml`` with each build
  (``MasterRunner(..., fmu_kind=...)``, ``--workers`` processes), wall time, and the
  largest difference between the two builds over every case and recorded signal.

Differences are ``max |python - native| / max |python|`` per recorded signal.

Run:  .venv/bin/python benchmarks/bench_native.py [--stop 12] [--eos] [--eos-stop 3 8]
      [--ssp] [--campaign] [--workers 2] [--repeat 3]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
KINDS = ("python", "native")

TRUSS_SCENARIO = ROOT / "scenarios/truss10_closed_loop.toml"
EOS_SCENARIO = ROOT / "scenarios/eos_budget.toml"
CAMPAIGN = ROOT / "campaigns/eos_budget.toml"
TRUSS = ("truss10_structure", "piezo_p243_30", "piezo_p243_40",
         "controller_truss10_strain_diag", "controller_truss10_strain_long", "excitation")
EOS_CASE = ["dist_swir.preset=swir_cryocooler", "ctrl_iso1.gain=0.27", "ctrl_iso2.gain=0.27",
            "ctrl_iso3.gain=0.27", "ctrl_swir.gain=0.1", "ctrl_vnir.gain=0.1"]

# One scenario run in a fresh process; Simulation.initialize and .run timed inside.
_CHILD = """
import json, sys, time, warnings
t0 = time.perf_counter()
warnings.simplefilter("ignore")
from orchestrator import run as run_module
from orchestrator import run_scenario
imports = time.perf_counter() - t0
phase = {}

class TimedSimulation(run_module.Simulation):
    def initialize(self):
        t = time.perf_counter()
        super().initialize()
        phase["initialize"] = time.perf_counter() - t

    def run(self, progress=None):
        t = time.perf_counter()
        super().run(progress)
        phase["steps"] = time.perf_counter() - t

run_module.Simulation = TimedSimulation
job = json.loads(sys.argv[1])
table, meta = run_scenario(job["scenario"], job["out"], fmu_dir=job["fmu_dir"],
                           fmu_kind=job["kind"], stop_time=job["stop"],
                           overrides=job["overrides"])
print(json.dumps({"child": time.perf_counter() - t0, "imports": imports, **phase,
                  "status": meta["status"]}))
"""

# Our master on an SSP archive: stepping time after initialisation.
_MASTER_SSP = """
import json, sys, time, warnings
warnings.simplefilter("ignore")
from orchestrator import Simulation, prepare, read_ssp
job = json.loads(sys.argv[1])
sim = Simulation(prepare(read_ssp(job["ssp"]).with_experiment(stop=job["stop"])))
try:
    sim.initialize()
    t0 = time.perf_counter()
    sim.run()
    seconds = time.perf_counter() - t0
finally:
    sim.close()
print(json.dumps({"steps": seconds}))
"""

# libcosim on the same archive (as tests/orchestrator/test_exactness.py LIBCOSIM_CHILD):
# the first base step (initialisation) untimed, then the rest.
_LIBCOSIM_SSP = """
import json, os, sys, time
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimObserver import CosimObserver
job = json.loads(sys.argv[1])
log_output_level(CosimLogLevel.WARNING)
ex = CosimExecution.from_ssp_file(job["ssp"])
ex.add_observer(CosimObserver.create_last_value())
ok = ex.step(1)
t0 = time.perf_counter()
ok = ok and ex.simulate_until(round(job["stop"] * 1e9))
seconds = time.perf_counter() - t0
print(json.dumps({"steps": seconds, "ok": bool(ok)}))
sys.stdout.flush()
sys.stderr.flush()
os._exit(0 if ok else 3)  # no interpreter teardown while pythonfmu slaves are alive
"""


def build(fmu_dir: Path, eos: bool) -> None:
    """Both builds of the ten-bay (and EOS, all-legs structure included) FMUs."""
    from fmutools.ensure import ensure_fmus

    ensure_fmus(TRUSS, fmu_dir, kind="native")  # builds the Python twins first
    if eos:
        from orchestrator.experiments import eos as eos_experiment

        eos_experiment.ensure_fmus(fmu_dir)


def fmu_steps(scenario: dict, stop: float) -> int:
    """Number of doStep calls of one run (every instance at its own period)."""
    return sum(round(stop / float(inst["period"])) for inst in scenario["fmus"].values())


def child(script: str, job: dict, timeout: float = 3600.0) -> tuple[float, dict]:
    """Run a child script on a job; its wall time (s) and its JSON report."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", script, json.dumps(job)],
                          capture_output=True, text=True, cwd=ROOT, timeout=timeout)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"child failed ({proc.returncode}): {proc.stderr.strip()[-2000:]}")
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    if report.get("status", "ok") != "ok":
        raise RuntimeError(f"run ended with status {report['status']}")
    return wall, report


def difference(a: dict, b: dict) -> tuple[float, str]:
    """Largest |a - b| / peak(a) over the signals of two tables, and its signal."""
    import numpy as np

    worst, where = 0.0, ""
    for name in a:
        x, y = np.asarray(a[name], float), np.asarray(b[name], float)
        peak = float(np.max(np.abs(x)))
        d = float(np.max(np.abs(x - y))) / peak if peak else float(np.max(np.abs(y)))
        if d > worst or not where:
            worst, where = d, name
    return worst, where


def end_to_end(label, scenario: Path, stop, overrides, fmu_dir, tmp, repeat) -> dict:
    """Best-of-`repeat` fresh-process runs with each build; phases of the best run."""
    from orchestrator.results import read_table

    n = fmu_steps(tomllib.loads(scenario.read_text()), stop)
    row = {"label": label, "stop": stop, "n": n}
    for kind in KINDS:
        runs = []
        for k in range(repeat):
            out = tmp / f"{label}-{stop:g}-{kind}-{k}".replace(" ", "_")
            job = {"scenario": str(scenario), "out": str(out), "fmu_dir": str(fmu_dir),
                   "kind": kind, "stop": stop, "overrides": overrides}
            wall, report = child(_CHILD, job)
            runs.append({"wall": wall, **report, "out": out})
        row[kind] = min(runs, key=lambda r: r["wall"])
    tables = [read_table(row[kind]["out"] / "results.parquet") for kind in KINDS]
    row["diff"], row["worst"] = difference(*tables)
    print(f"{label}, {stop:g} s: Python {row['python']['wall']:.2f} s, "
          f"native {row['native']['wall']:.2f} s", flush=True)
    return row


def bare_step_cost(fmu: Path, inputs: list[str], n: int = 5000) -> float:
    """Seconds per set/doStep/get of one FMU in a bare fmpy loop (no master)."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmu))
    var = {v.name: v for v in md.modelVariables}
    outs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    ins = [var[name].valueReference for name in inputs]
    unzip = extract(str(fmu))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="b")
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    values = [1.0] * len(ins)
    t0 = time.perf_counter()
    for k in range(n):
        slave.setReal(ins, values)
        slave.doStep(currentCommunicationPoint=k * 1e-3, communicationStepSize=1e-3)
        slave.getReal(outs)
    cost = (time.perf_counter() - t0) / n
    slave.terminate()
    slave.freeInstance()
    return cost


def ssp_runs(stop, fmu_dir, tmp, repeat) -> dict:
    """Seconds of stepping (best of `repeat`): {(runner, kind): s}; SSP per build."""
    import warnings

    from orchestrator import load_scenario, prepare, write_ssp

    base = load_scenario(TRUSS_SCENARIO).with_experiment(algorithm="jacobi", stop=stop)
    best = {}
    for kind in KINDS:
        ssp = tmp / f"truss10_closed_loop-{kind}.ssp"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            write_ssp(prepare(base.with_experiment(fmu_kind=kind), fmu_dir), ssp)
        for runner, script in (("master", _MASTER_SSP), ("libcosim", _LIBCOSIM_SSP)):
            try:
                best[runner, kind] = min(
                    child(script, {"ssp": str(ssp), "stop": stop}, timeout=900)[1]["steps"]
                    for _ in range(repeat))
            except (RuntimeError, subprocess.TimeoutExpired) as exc:
                best[runner, kind] = f"failed: {str(exc).splitlines()[0][:120]}"
            print(f"SSP, {runner}, {kind} FMUs: {best[runner, kind]}", flush=True)
    return best


def campaign_runs(fmu_dir, tmp, workers, stop=None) -> dict:
    """The EOS budget campaign with each build: wall times and the largest difference."""
    from orchestrator.campaign import MasterRunner, campaign_from_dict, run_campaign
    from orchestrator.results import read_table

    data = tomllib.loads(CAMPAIGN.read_text())
    if stop is not None:
        data["campaign"]["stop"] = stop
    camp = campaign_from_dict(data, CAMPAIGN.parent)
    result = {"n_cases": len(camp.cases),
              "n": fmu_steps(camp.cases[0].scenario, data["campaign"]["stop"]),
              "stop": data["campaign"]["stop"]}
    folders = {}
    os.environ["PYTHONWARNINGS"] = "ignore"  # the workers' UnconnectedInputWarning
    for kind in KINDS:
        folders[kind] = tmp / f"campaign-{kind}"
        runner = MasterRunner(camp.scenario_dir, fmu_dir=fmu_dir, fmu_kind=kind)
        t0 = time.perf_counter()
        done = run_campaign(camp, folders[kind], runner, workers=workers, progress=False)
        result[kind] = time.perf_counter() - t0
        if done.n_failed:
            raise RuntimeError(f"campaign with {kind} FMUs: {done.failures}")
        print(f"campaign, {kind} FMUs: {result[kind]:.1f} s", flush=True)
    keys = {kind: {c["label"]: c["key"] for c in
                   json.loads((folders[kind] / "campaign.json").read_text())["cases"]}
            for kind in KINDS}
    worst = (0.0, "", "")
    for label, key in keys["python"].items():
        a, b = (read_table(folders[kind] / "cases" / keys[kind][label] / "results.parquet")
                for kind in KINDS)
        d, signal = difference(a, b)
        worst = max(worst, (d, label, signal))
    result["diff"], result["case"], result["signal"] = worst
    result["n_signals"] = len(a) - 1
    return result


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stop", type=float, default=12.0, help="ten-bay stop time (s)")
    parser.add_argument("--eos", action="store_true", help="also one EOS budget case")
    parser.add_argument("--eos-stop", type=float, nargs="+", default=[3.0, 8.0],
                        help="EOS stop time(s) (s); the campaign's cases last 8 s")
    parser.add_argument("--ssp", action="store_true",
                        help="also the ten-bay SSP in our master and in libcosim")
    parser.add_argument("--campaign", action="store_true",
                        help="also the 24-case EOS budget campaign with each build")
    parser.add_argument("--campaign-stop", type=float, default=None,
                        help="campaign stop time (s); default the campaign's own (8 s)")
    parser.add_argument("--workers", type=int, default=2, help="campaign worker processes")
    parser.add_argument("--repeat", type=int, default=3, help="runs per build (best kept)")
    args = parser.parse_args(argv)
    eos = args.eos or args.campaign
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_native_") as tmp:
        tmp = Path(tmp)
        fmu_dir = tmp / "fmus"
        t0 = time.perf_counter()
        build(fmu_dir, eos)
        print(f"built both builds in {time.perf_counter() - t0:.1f} s", flush=True)
        rows.append(end_to_end("ten-bay closed loop", TRUSS_SCENARIO, args.stop, [],
                               fmu_dir, tmp, args.repeat))
        bare = [(name, {"python": bare_step_cost(fmu_dir / "python" / f"{name}.fmu", ins),
                        "native": bare_step_cost(fmu_dir / f"{name}.fmu", ins)})
                for name, ins in (("truss10_structure", ["fc_diag", "fc_long"]),
                                  ("piezo_p243_40", ["v_cmd", "elongation"]),
                                  ("controller_truss10_strain_diag", ["y1", "r1"]))]
        if args.eos:
            rows += [end_to_end("EOS budget case", EOS_SCENARIO, stop, EOS_CASE, fmu_dir,
                                tmp, args.repeat) for stop in args.eos_stop]
        ssp = ssp_runs(args.stop, fmu_dir, tmp, args.repeat) if args.ssp else None
        camp = (campaign_runs(fmu_dir, tmp, args.workers, args.campaign_stop)
                if args.campaign else None)

    print("\n| scenario | simulated (s) | FMU steps | Python FMUs (s) | native FMUs (s) "
          "| speed-up | Python us/FMU step | native us/FMU step | max difference |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        t_py, t_nat, n = r["python"]["wall"], r["native"]["wall"], r["n"]
        print(f"| {r['label']} | {r['stop']:g} | {n} | {t_py:.2f} | {t_nat:.2f} "
              f"| {t_py / t_nat:.1f}x | {1e6 * t_py / n:.1f} | {1e6 * t_nat / n:.1f} "
              f"| {r['diff']:.1e} ({r['worst']}) |")
    print("\nWall time per run in a fresh process (best of --repeat), start-up included; "
          "us/FMU step = wall time / FMU steps (master overhead included).")

    print("\nWhere the time goes (the best run of each build; start-up = wall - steps):\n")
    print("| scenario | build | wall (s) | process + imports (s) | initialize (s) "
          "| steps (s) | start-up (s) | us/FMU step, steps only |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        for kind in KINDS:
            p = r[kind]
            before = p["wall"] - p["child"] + p["imports"]
            print(f"| {r['label']}, {r['stop']:g} s | {kind} | {p['wall']:.2f} | {before:.2f} "
                  f"| {p['initialize']:.2f} | {p['steps']:.2f} | {p['wall'] - p['steps']:.2f} "
                  f"| {1e6 * p['steps'] / r['n']:.1f} |")
        steps = r["python"]["steps"] / r["native"]["steps"]
        start = ((r["python"]["wall"] - r["python"]["steps"])
                 / (r["native"]["wall"] - r["native"]["steps"]))
        print(f"| {r['label']}, {r['stop']:g} s | Python / native | | | | {steps:.1f}x "
              f"| {start:.1f}x | |")

    print("\n| FMU (bare fmpy loop, no master) | Python us/step | native us/step | "
          "speed-up |")
    print("|---|---:|---:|---:|")
    for name, cost in bare:
        print(f"| {name} | {1e6 * cost['python']:.1f} | {1e6 * cost['native']:.1f} | "
              f"{cost['python'] / cost['native']:.1f}x |")

    if ssp is not None:
        n = rows[0]["n"]
        print(f"\nTen-bay closed loop as SSP (Jacobi), {args.stop:g} s, {n} FMU steps; "
              "stepping only, best of --repeat:\n")
        print("| runner | FMUs | stepping (s) | us/FMU step |")
        print("|---|---|---:|---:|")
        for (runner, kind), s in ssp.items():
            name = "jitterfmu master" if runner == "master" else "libcosim (libcosimpy)"
            cells = (f"{s:.2f} | {1e6 * s / n:.1f}" if isinstance(s, float) else f"{s} | -")
            print(f"| {name} | {kind} | {cells} |")

    if camp is not None:
        print(f"\nEOS budget campaign: {camp['n_cases']} cases x {camp['stop']:g} s, "
              f"{camp['n']} FMU steps per case, {args.workers} workers:\n")
        print("| build | wall (s) | us/FMU step (wall / all FMU steps) |")
        print("|---|---:|---:|")
        total = camp["n_cases"] * camp["n"]
        for kind in KINDS:
            print(f"| {kind} | {camp[kind]:.1f} | {1e6 * camp[kind] / total:.1f} |")
        print(f"| Python / native | {camp['python'] / camp['native']:.1f}x | |")
        print(f"\nLargest difference over {camp['n_cases']} cases x {camp['n_signals']} "
              f"recorded signals: {camp['diff']:.1e} of the signal's peak "
              f"({camp['signal']}, case {camp['case']!r})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
