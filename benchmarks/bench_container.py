"""The 8 s EOS budget case as one container FMU in FMPy against ``jitterfmu run``.

Same machine, same run: one EOS budget case (``scenarios/eos_budget.toml``, 21
instances, SWIR cryocooler, reaction wheels, VNIR pointing and CERES scan on, isolation
on) over ``--stop`` seconds, twice per repeat:

* the master: ``run_scenario`` of the scenario (native FMUs, the compiled tick loop);
* the container: ``nativefmu.container.export_fmu`` of the same scenario (once, not
  timed in the loop), stepped by ``fmpy.simulate_fmu`` at the base step (1 ms), every
  recorded signal as an output, and at 4 ms (four base ticks per doStep: the same
  values at every fourth instant, fewer FMPy calls);
* the FMI 3.0 container (``export_fmu(..., fmi=3)``) in FMPy at 1 ms.

Then where the container's time goes at the base step (``--no-breakdown`` skips it),
each best of ``--repeat``, FMPy's ``FMU2Slave`` on the FMI 2.0 container:

* the container's C alone: one ``doStep`` of all the ticks (the same calls as the
  master's compiled loop, which is timed too: ``FastLoop.run`` in the master's run);
* one ``doStep`` per base tick and nothing else (adds one ctypes call per tick);
* ``getReal`` of every output after each tick, alone (FMPy builds the ctypes arrays and
  the list in Python at each call);
* the rest of ``simulate_fmu`` (recording, loading) is the 1 ms time minus those.

Both include loading and initialisation in this process; the best of ``--repeat`` is
printed, with the largest difference between the two tables relative to each signal's
peak.

Run:  .venv/bin/python benchmarks/bench_container.py [--stop 8] [--repeat 3] [--no-breakdown]
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
from orchestrator.cosim import fastloop

ROOT = Path(__file__).resolve().parents[1]
EVENTS = ["dist_swir.preset=swir_cryocooler", "dist_rwa.preset=rwa",
          "dist_vnir.preset=vnir_pointing", "dist_ceres.preset=ceres_scan",
          "ctrl_iso1.gain=0.27", "ctrl_iso2.gain=0.27", "ctrl_iso3.gain=0.27",
          "ctrl_swir.gain=0.1", "ctrl_vnir.gain=0.1"]


def _slave(fmu: Path, unzip: str):
    """An initialised FMU2Slave of the FMI 2.0 container."""
    from fmpy.fmi2 import FMU2Slave

    md = fmpy.read_model_description(str(fmu))
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    vrs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    return s, vrs


def breakdown(sc, fmu: Path, stop: float, repeat: int) -> dict:
    """Seconds of each part of the container's base-step run in FMPy (best of repeat)."""
    unzip = fmpy.extract(str(fmu))
    n = int(round(stop / 1e-3))
    best = {"master's compiled loop (FastLoop.run)": np.inf,
            "container C alone (one doStep of all ticks)": np.inf,
            "one doStep per tick": np.inf, "getReal of every output, per tick": np.inf}
    run = fastloop.FastLoop.run
    spent = [0.0]

    def timed_run(self, *a, **kw):
        t0 = time.perf_counter()
        try:
            return run(self, *a, **kw)
        finally:
            spent[0] += time.perf_counter() - t0

    for _ in range(repeat):
        spent[0] = 0.0
        fastloop.FastLoop.run = timed_run
        try:
            run_scenario(sc, stop_time=stop)
        finally:
            fastloop.FastLoop.run = run
        best["master's compiled loop (FastLoop.run)"] = min(
            best["master's compiled loop (FastLoop.run)"], spent[0])
        s, vrs = _slave(fmu, unzip)
        t0 = time.perf_counter()
        s.doStep(0.0, n * 1e-3)
        key = "container C alone (one doStep of all ticks)"
        best[key] = min(best[key], time.perf_counter() - t0)
        s.freeInstance()
        s, vrs = _slave(fmu, unzip)
        t0 = time.perf_counter()
        for k in range(n):
            s.doStep(k * 1e-3, 1e-3)
        t1 = time.perf_counter()
        for _k in range(n):
            s.getReal(vrs)
        t2 = time.perf_counter()
        best["one doStep per tick"] = min(best["one doStep per tick"], t1 - t0)
        best["getReal of every output, per tick"] = min(
            best["getReal of every output, per tick"], t2 - t1)
        s.freeInstance()
    return best


def main() -> None:
    """Time both ways and print one line each."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stop", type=float, default=8.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-breakdown", action="store_true",
                    help="skip timing the parts of the container's run")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    sc = load_scenario(ROOT / "scenarios" / "eos_budget.toml").with_overrides(EVENTS)
    with tempfile.TemporaryDirectory() as tmp:
        fmu = export_fmu(sc, Path(tmp) / "eos.fmu", windows=False)
        fmu3 = export_fmu(sc, Path(tmp) / "eos3.fmu", windows=False, fmi=3)
        best = {"jitterfmu run (master)": np.inf, "container FMU in FMPy": np.inf,
                "container, 4 ms step": np.inf, "FMI 3.0 container, 1 ms": np.inf}
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
            t3 = time.perf_counter()
            best["container, 4 ms step"] = min(best["container, 4 ms step"], t3 - t2)
            res3 = fmpy.simulate_fmu(str(fmu3), stop_time=args.stop, output_interval=1e-3,
                                     output=list(sc.record))
            best["FMI 3.0 container, 1 ms"] = min(best["FMI 3.0 container, 1 ms"],
                                                  time.perf_counter() - t3)
        parts = None if args.no_breakdown else breakdown(sc, fmu, args.stop, args.repeat)
    worst = worst3 = 0.0
    for ref in sc.record:
        a, b = np.asarray(table[ref], float), np.asarray(res[ref], float)
        peak = np.max(np.abs(a))
        if peak > 0:
            worst = max(worst, float(np.max(np.abs(a - b)) / peak))
            worst3 = max(worst3, float(np.max(np.abs(a - np.asarray(res3[ref]))) / peak))
    steps = int(round(args.stop / 1e-3))
    print(f"EOS budget case, {args.stop:g} s ({len(sc.instances)} instances, {steps} base "
          f"steps), best of {args.repeat}:")
    for name, t in best.items():
        print(f"  {name:26s} {t:7.3f} s")
    for name in ("container FMU in FMPy", "container, 4 ms step", "FMI 3.0 container, 1 ms"):
        print(f"  master / {name:24s} {best['jitterfmu run (master)'] / best[name]:7.2f}x")
    print(f"  largest difference        {worst:.3g} of peak ({len(sc.record)} signals); "
          f"FMI 3.0 container {worst3:.3g}")
    if parts is not None:
        print("where the time goes at the base step:")
        for name, t in parts.items():
            print(f"  {name:44s} {t:7.3f} s")
        rest = (best["container FMU in FMPy"] - parts["one doStep per tick"]
                - parts["getReal of every output, per tick"])
        print(f"  {'rest of simulate_fmu (recording, loading)':44s} {rest:7.3f} s")


if __name__ == "__main__":
    main()
