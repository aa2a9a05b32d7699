"""Cost per step of every FMU under the hosts' time styles, side by side in one run.

Each FMU (native and Python) is stepped at 1 ms through fmpy with the same inputs
under four hosts:

* ``exact``: the tick ``k / 1000`` and the period (the reference);
* ``(k+1)h-kh``: FMPy's arithmetic (12 distinct step values over 8 s);
* ``t+=h``: an accumulated time;
* ``new step`` (structures only): every step a step size the FMU has not seen (50 sizes
  1e-8 apart, cycled, more than the structure's cache of 8): what the structure FMU paid
  at almost every step under ``(k+1)h-kh`` before a step within rounding of a known one
  was that step (it re-discretised whenever the value changed).  The other FMUs do not
  discretise per step size (the piezo with ``coupling = 1`` refuses another step).

The time is the wall time of ``setReal + doStep + getReal`` per step (µs), best of
``--repeat`` runs, from the second step on (the Python structure discretises at its first
step); the ``new step`` column runs ``--new-steps`` steps only (a stiff structure's
discretisation takes tens of milliseconds to a second).

With ``--accuracy N`` it also compares the native and Python structures over ``N`` steps
(random loads, max over outputs of the error relative to each output's peak) on steps not
declared at build time (2 ms, 0.5 ms: discretised in C and in scipy) and on 1 ms passed
as ``(k+1)h - kh``.

Run:  .venv/bin/python benchmarks/bench_host_time.py [--steps 2000] [--new-steps 20]
      [--repeat 3] [--model eos_testbed_structure ...] [--accuracy 8000]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from fractions import Fraction
from pathlib import Path

import numpy as np

MODELS = ("truss10_structure", "eos_testbed_structure", "piezo_p845_37",
          "controller_eos_isolation", "acs", "disturbance", "excitation")
H = 1e-3


def hosts(n: int, n_new: int) -> dict:
    acc, t = [], 0.0
    for _ in range(n):
        acc.append((t, H))
        t += H
    return {
        "exact": [(float(Fraction(k, 1000)), H) for k in range(n)],
        "(k+1)h-kh": [(k * H, (k + 1) * H - k * H) for k in range(n)],
        "t+=h": acc,
        "new step": [(k * H, H * (1 + 1e-8 * (1 + k % 50))) for k in range(n_new)],
    }


def run_fmu(path: Path, steps: list, u: np.ndarray | None = None):
    """Outputs after every step and the wall time per step from the second step on (s)."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(path))
    ins = [v.valueReference for v in md.modelVariables
           if v.causality == "input" and v.type == "Real"]
    outs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    if u is None:
        u = np.random.default_rng(1).standard_normal((len(steps), len(ins))) * 1e-3
    unzipped = extract(str(path))
    try:
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, instanceName="b",
                        modelIdentifier=md.coSimulation.modelIdentifier)
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        y = np.empty((len(steps), len(outs)))
        for k, (t, h) in enumerate(steps):
            if k == 1:
                t0 = time.perf_counter()
            if ins:
                fmu.setReal(ins, u[k].tolist())
            fmu.doStep(t, h)
            y[k] = fmu.getReal(outs)
        seconds = (time.perf_counter() - t0) / (len(steps) - 1)
        fmu.terminate()
        fmu.freeInstance()
    finally:
        shutil.rmtree(unzipped, ignore_errors=True)
    return y, seconds


def per_step_us(path: Path, steps: list, repeat: int) -> float:
    return min(run_fmu(path, steps)[1] for _ in range(repeat)) * 1e6


def accuracy(paths: dict, n: int) -> None:
    """Native against Python on the structures, max over outputs of the error relative
    to each output's peak: steps not declared at build time, and 1 ms as (k+1)h - kh."""
    print(f"native vs Python, {n} steps, random loads (max error / peak over outputs)")
    for model in [m for m in paths["native"] if m.endswith("_structure")]:
        for label, steps in (("2 ms (undeclared)", [(k * 2e-3, 2e-3) for k in range(n)]),
                             ("0.5 ms (undeclared)", [(k * 5e-4, 5e-4) for k in range(n)]),
                             ("1 ms as (k+1)h-kh", hosts(n, 0)["(k+1)h-kh"])):
            y_n, _ = run_fmu(paths["native"][model], steps)   # the same seeded loads
            y_p, _ = run_fmu(paths["python"][model], steps)
            peak = np.max(np.abs(y_p), axis=0)
            err = np.max(np.abs(y_n - y_p), axis=0) / np.where(peak > 0, peak, 1.0)
            print(f"  {model:<24} {label:<22} {err.max():.1e}", flush=True)


def main(argv=None) -> None:
    from fmutools.ensure import ensure_fmus

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=2000)
    p.add_argument("--new-steps", type=int, default=20)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--model", action="append", choices=MODELS)
    p.add_argument("--accuracy", type=int, metavar="N", default=0,
                   help="also compare native and Python structures over N steps")
    args = p.parse_args(argv)
    models = args.model or list(MODELS)
    styles = hosts(args.steps, args.new_steps)
    with tempfile.TemporaryDirectory() as tmp:
        paths = {kind: ensure_fmus(models, Path(tmp), kind=kind)
                 for kind in ("native", "python")}
        print(f"µs per step, best of {args.repeat}; {args.steps} steps "
              f"({args.new_steps} for 'new step')")
        print(f"{'model':<26} {'build':<7}" + "".join(f"{s:>12}" for s in styles))
        for model in models:
            for kind in ("native", "python"):
                cells = [f"{per_step_us(paths[kind][model], steps, args.repeat):12.1f}"
                         if style != "new step" or model.endswith("_structure")
                         else f"{'-':>12}" for style, steps in styles.items()]
                print(f"{model:<26} {kind:<7}" + "".join(cells), flush=True)
        if args.accuracy:
            accuracy(paths, args.accuracy)


if __name__ == "__main__":
    main()
