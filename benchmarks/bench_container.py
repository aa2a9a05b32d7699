"""The 8 s EOS budget case as one container FMU in FMPy against ``jitterfmu run``.

Same machine, same run: one EOS budget case (``scenarios/eos_budget.toml``, 21
instances, SWIR cryocooler, reaction wheels, VNIR pointing and CERES scan on, isolation
on) over ``--stop`` seconds, twice per repeat:

* the master: ``run_scenario`` of the scenario (native FMUs, the compiled tick loop);
* the container: ``nativefmu.container.export_fmu`` of the same scenario (once, not
  timed in the loop), stepped by ``fmpy.simulate_fmu`` at the base step (1 ms), every
  recorded signal as an output, and at 4 ms (four base ticks per doStep: the same
  values at every fourth instant, fewer FMPy calls).

Both include loading and initialisation in this process; the best of ``--repeat`` is
printed, with the largest difference between the two tables relative to each signal's
peak.

Run:  .venv/bin/python benchmarks/bench_container.py [--stop 8] [--repeat 3]
"""

from __future__ import annotations

import argparse
import tempfile
import time
import warnings
from pathlib import Path

import fmpy
import numpy as np

from nativefmu.container import export_fmu
from orchestrator import load_scenario, run_scenario

ROOT = Path(__file__).resolve().parents[1]
EVENTS = ["dist_swir.preset=swir_cryocooler", "dist_rwa.preset=rwa",
          "dist_vnir.preset=vnir_pointing", "dist_ceres.preset=ceres_scan",
          "ctrl_iso1.gain=0.27", "ctrl_iso2.gain=0.27", "ctrl_iso3.gain=0.27",
          "ctrl_swir.gain=0.1", "ctrl_vnir.gain=0.1"]


def main() -> None:
    """Time both ways and print one line each."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stop", type=float, default=8.0)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    sc = load_scenario(ROOT / "scenarios" / "eos_budget.toml").with_overrides(EVENTS)
    with tempfile.TemporaryDirectory() as tmp:
        fmu = export_fmu(sc, Path(tmp) / "eos.fmu", windows=False)
        best = {"jitterfmu run (master)": np.inf, "container FMU in FMPy": np.inf,
                "container, 4 ms step": np.inf}
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            table, _ = run_scenario(sc, stop_time=args.stop)
            t1 = time.perf_counter()
            res = fmpy.simulate_fmu(str(fmu), stop_time=args.stop, output_interval=1e-3,
                                    output=list(sc.record))
            t2 = time.perf_counter()
            best["jitterfmu run (master)"] = min(best["jitterfmu run (master)"], t1 - t0)
            best["container FMU in FMPy"] = min(best["container FMU in FMPy"], t2 - t1)
            fmpy.simulate_fmu(str(fmu), stop_time=args.stop, output_interval=4e-3,
                              output=list(sc.record))
            best["container, 4 ms step"] = min(best["container, 4 ms step"],
                                               time.perf_counter() - t2)
    worst = 0.0
    for ref in sc.record:
        a, b = np.asarray(table[ref], float), np.asarray(res[ref], float)
        peak = np.max(np.abs(a))
        if peak > 0:
            worst = max(worst, float(np.max(np.abs(a - b)) / peak))
    steps = int(round(args.stop / 1e-3))
    print(f"EOS budget case, {args.stop:g} s ({len(sc.instances)} instances, {steps} base "
          f"steps), best of {args.repeat}:")
    for name, t in best.items():
        print(f"  {name:26s} {t:7.3f} s")
    for name in ("container FMU in FMPy", "container, 4 ms step"):
        print(f"  master / {name:17s} {best['jitterfmu run (master)'] / best[name]:7.2f}x")
    print(f"  largest difference        {worst:.3g} of peak ({len(sc.record)} signals)")


if __name__ == "__main__":
    main()
