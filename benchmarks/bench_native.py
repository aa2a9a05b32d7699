"""Native (C99) FMUs beside their Python twins: same scenario, same master, one run.

Builds both flavours of the FMUs a scenario uses into a temporary folder, then runs the
scenario with each flavour in a fresh Python process (``jitterfmu``'s master on fmpy),
so the wall time includes everything a user waits for: process start, loading the
FMUs (the Python FMUs import numpy and scipy inside), initialisation and the steps.
Reports wall time, cost per FMU step and the largest difference between the two result
tables (relative to each signal's peak).

Scenarios: the ten-bay closed loop (``scenarios/truss10_closed_loop.toml``, 12 s, six
FMUs) and, with ``--eos``, one EOS budget case (``scenarios/eos_budget.toml``, 21
instances, SWIR cryocooler on, isolation on).

Run:  .venv/bin/python benchmarks/bench_native.py [--stop 12] [--eos] [--repeat 3]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

TRUSS = ("truss10_structure", "piezo_p243_30", "piezo_p243_40",
         "controller_truss10_strain_diag", "controller_truss10_strain_long", "excitation")
EOS = ("eos_testbed_structure", "piezo_p845_37", "controller_eos_isolation",
       "controller_testbed_isolation", "acs", "disturbance")
EOS_CASE = ["dist_swir.preset=swir_cryocooler", "ctrl_iso1.gain=0.27", "ctrl_iso2.gain=0.27",
            "ctrl_iso3.gain=0.27", "ctrl_swir.gain=0.1", "ctrl_vnir.gain=0.1"]

_CHILD = """
import json, sys, time, warnings
t0 = time.perf_counter()
warnings.simplefilter("ignore")
from orchestrator import run_scenario
table, meta = run_scenario(sys.argv[1], sys.argv[2], fmu_dir=sys.argv[3],
                           stop_time=float(sys.argv[4]), overrides=sys.argv[5:])
print(json.dumps({"seconds": time.perf_counter() - t0, "status": meta["status"]}))
"""


def build(models, folder: Path) -> dict[str, Path]:
    """Python FMUs in folder/py, native twins (from those) in folder/native."""
    from fmutools.build import build_fmu
    from fmutools.registry import collect_specs

    from nativefmu import build_native

    out = {"python": folder / "py", "native": folder / "native"}
    for spec in collect_specs(list(models)):
        python_fmu = build_fmu(spec, out["python"])
        build_native(spec, out["native"], python_fmu=python_fmu, windows=False)
    return out


def fmu_steps(scenario: Path, stop: float) -> int:
    """Number of doStep calls of one run (every instance at its own period)."""
    import tomllib

    spec = tomllib.loads(scenario.read_text())
    return sum(round(stop / inst["period"]) for inst in spec["fmus"].values())


def run(scenario, out_dir, fmu_dir, stop, overrides) -> float:
    cmd = [sys.executable, "-c", _CHILD, str(scenario), str(out_dir), str(fmu_dir), repr(stop),
           *overrides]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"run failed: {proc.stderr.strip()[-2000:]}")
    status = json.loads(proc.stdout.strip().splitlines()[-1])["status"]
    if status != "ok":
        raise RuntimeError(f"run ended with status {status}")
    return wall


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


def difference(dir_a: Path, dir_b: Path) -> float:
    """Largest |a - b| / peak(a) over the recorded signals of two runs."""
    import numpy as np

    from orchestrator.results import read_table

    a, b = read_table(dir_a / "results.parquet"), read_table(dir_b / "results.parquet")
    worst = 0.0
    for name in a.keys():
        x, y = np.asarray(a[name], float), np.asarray(b[name], float)
        peak = float(np.max(np.abs(x)))
        worst = max(worst, float(np.max(np.abs(x - y))) / peak if peak else 0.0)
    return worst


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stop", type=float, default=12.0, help="ten-bay stop time (s)")
    parser.add_argument("--eos", action="store_true", help="also one EOS budget case")
    parser.add_argument("--eos-stop", type=float, default=3.0, help="EOS stop time (s)")
    parser.add_argument("--repeat", type=int, default=3, help="runs per flavour (best kept)")
    args = parser.parse_args(argv)
    cases = [("ten-bay closed loop", ROOT / "scenarios/truss10_closed_loop.toml", args.stop,
              [], TRUSS)]
    if args.eos:
        cases.append(("EOS budget case", ROOT / "scenarios/eos_budget.toml", args.eos_stop,
                      EOS_CASE, EOS))
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_native_") as tmp:
        tmp = Path(tmp)
        for label, scenario, stop, overrides, models in cases:
            t0 = time.perf_counter()
            folders = build(models, tmp / label.replace(" ", "_"))
            print(f"{label}: built both flavours in {time.perf_counter() - t0:.1f} s",
                  flush=True)
            n = fmu_steps(scenario, stop)
            best = {}
            for flavour, fmu_dir in folders.items():
                times = [run(scenario, tmp / f"{label}-{flavour}-{k}".replace(" ", "_"),
                             fmu_dir, stop, overrides) for k in range(args.repeat)]
                best[flavour] = min(times)
            diff = difference(tmp / f"{label}-python-0".replace(" ", "_"),
                              tmp / f"{label}-native-0".replace(" ", "_"))
            rows.append((label, stop, n, best["python"], best["native"], diff))
            if label.startswith("ten-bay"):
                bare = [(name, ins, {f: bare_step_cost(folders[f] / f"{name}.fmu", ins)
                                     for f in folders})
                        for name, ins in (("truss10_structure", ["fc_diag", "fc_long"]),
                                          ("piezo_p243_40", ["v_cmd", "elongation"]),
                                          ("controller_truss10_strain_diag", ["y1", "r1"]))]
    print()
    print("| scenario | simulated (s) | FMU steps | Python FMUs (s) | native FMUs (s) "
          "| speed-up | Python us/FMU step | native us/FMU step | max difference |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, stop, n, t_py, t_nat, diff in rows:
        print(f"| {label} | {stop:g} | {n} | {t_py:.2f} | {t_nat:.2f} | {t_py / t_nat:.1f}x "
              f"| {1e6 * t_py / n:.1f} | {1e6 * t_nat / n:.1f} | {diff:.1e} |")
    print("\n| FMU (bare fmpy loop, no master) | Python us/step | native us/step | "
          "speed-up |")
    print("|---|---:|---:|---:|")
    for name, _, cost in bare:
        print(f"| {name} | {1e6 * cost['python']:.1f} | {1e6 * cost['native']:.1f} | "
              f"{cost['python'] / cost['native']:.1f}x |")
    print("\nWall time per run in a fresh process (best of --repeat), start-up included; "
          "us/FMU step = wall time / FMU steps (master overhead included).")
    return 0


if __name__ == "__main__":
    sys.exit(main())
