"""Native FMUs as FMI 2.0 and as FMI 3.0: same scenarios, same master, one run.

Builds the FMI 2.0 native FMUs the scenarios use (``fmutools.ensure.ensure_fmus``, into
a temporary folder) and their FMI 3.0 builds from the same Python twins
(``nativefmu.build.build_native(..., fmi=3)``), plus a mixed folder (structure,
controllers and disturbance FMI 3.0, the rest FMI 2.0), then runs each scenario with
each folder in this process, alternating, best of ``--repeat`` (after one warm-up run
each), and prints the wall time of ``run_scenario`` (loading, initialisation, steps,
writing the results) and the largest difference between the tables
(``max |a - b|`` over every recorded signal and sample; 0 means bit for bit).

Cases: the ten-bay closed loop (``scenarios/truss10_closed_loop.toml``, ``--stop``
seconds) and one EOS budget case (``scenarios/eos_budget.toml``, 21 instances, SWIR
cryocooler and RWA on, isolation on, ``--eos-stop`` seconds).

Run:  .venv/bin/python benchmarks/bench_fmi3.py [--stop 12] [--eos-stop 8] [--repeat 3]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CASES = {
    "ten-bay closed loop": ("truss10_closed_loop.toml", []),
    "EOS budget case": ("eos_budget.toml",
                        ["dist_swir.preset=swir_cryocooler", "dist_rwa.preset=rwa",
                         "ctrl_iso1.gain=0.27", "ctrl_iso2.gain=0.27", "ctrl_iso3.gain=0.27",
                         "ctrl_swir.gain=0.1", "ctrl_vnir.gain=0.1"]),
}
MODELS = ("truss10_structure", "piezo_p243_30", "piezo_p243_40",
          "controller_truss10_strain_diag", "controller_truss10_strain_long", "excitation",
          "acs", "disturbance", "eos_testbed_structure", "piezo_p845_37",
          "controller_eos_isolation", "controller_testbed_isolation")
MIXED_FMI3 = ("truss10_structure", "eos_testbed_structure", "controller_truss10_strain_diag",
              "controller_eos_isolation", "disturbance")


def folders(tmp: Path) -> dict:
    """{"FMI 2.0": dir, "FMI 3.0": dir, "mixed": dir} of built FMUs."""
    from fmutools.ensure import ensure_fmus
    from fmutools.registry import collect_specs
    from nativefmu.build import build_native

    two = tmp / "fmi2"
    ensure_fmus(MODELS, two)
    three, mixed = tmp / "fmi3", tmp / "mixed"
    mixed.mkdir()
    for spec in collect_specs(list(MODELS)):
        name = f"{spec.model_identifier}.fmu"
        build_native(spec, three, python_fmu=two / "python" / name, windows=False, fmi=3)
        shutil.copy2((three if spec.model_identifier in MIXED_FMI3 else two) / name,
                     mixed / name)
    return {"FMI 2.0": two, "FMI 3.0": three, "mixed": mixed}


def run_once(scenario: str, fmu_dir: Path, out: Path, stop: float, overrides) -> tuple:
    from orchestrator import run_scenario

    t0 = time.perf_counter()
    table, meta = run_scenario(ROOT / "scenarios" / scenario, out, fmu_dir=fmu_dir,
                               stop_time=stop, overrides=list(overrides))
    dt = time.perf_counter() - t0
    assert meta["status"] == "ok", meta["status"]
    return dt, table, meta


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--stop", type=float, default=12.0, help="ten-bay stop time (s)")
    p.add_argument("--eos-stop", type=float, default=8.0, help="EOS case stop time (s)")
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args()
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory(prefix="bench_fmi3_") as tmp:
        tmp = Path(tmp)
        dirs = folders(tmp)
        print(f"{'scenario':22s} {'build':8s} {'best (s)':>9s} {'max diff vs FMI 2.0':>20s}")
        for label, (scenario, overrides) in CASES.items():
            stop = args.stop if scenario.startswith("truss") else args.eos_stop
            best, tables = {}, {}
            for kind, d in dirs.items():   # warm-up: unpacking, compiled loop, page cache
                run_once(scenario, d, tmp / "out", stop, overrides)
            for _ in range(args.repeat):
                for kind, d in dirs.items():
                    dt, tables[kind], _ = run_once(scenario, d, tmp / "out", stop, overrides)
                    best[kind] = min(best.get(kind, dt), dt)
            ref = tables["FMI 2.0"]
            for kind in dirs:
                diff = max(float(np.max(np.abs(np.asarray(tables[kind][k], float)
                                               - np.asarray(ref[k], float))))
                           for k in ref.keys())
                print(f"{label:22s} {kind:8s} {best[kind]:9.3f} {diff:20.3g}")


if __name__ == "__main__":
    main()
