"""Weekly analyses on the EOS budget: RWA wheel-speed sweep and Monte Carlo, side by side.

Run::

    .venv/bin/python benchmarks/bench_linear_analyses.py [--samples 20] [--repeat 3]

* **RWA sweep**: 500 wheel speeds 0-6000 rpm, all 5 instruments x 3 axes, isolation off
  and on (``campaigns/eos_rwa_sweep.toml``), steady state on the linear engine; beside it
  the cost of the alternative, one co-simulated case per speed (the budget's RWA case,
  8 s at 1 kHz, timed here) times 500.  ``--repeat`` sweeps from scratch, each on a
  fresh runner: the median is printed, and the range.
* **Monte Carlo**: the budget (12 events x 2 configurations) with modal frequencies
  +-5 % and damping x0.5-2 (every mode on its own) and amplitudes +-20 % (every source
  on its own), ``--samples`` samples, extrapolated to 1000; beside it 1000 x 24
  co-simulated cases at the measured case cost; ``--workers`` processes (one BLAS
  thread each).  Peak memory of this process is printed with both sample counts: it
  does not grow with the samples.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _measure import peak_rss_mb  # noqa: E402

import numpy as np  # noqa: E402

from orchestrator.analysis.uncertainty import Distribution, Uncertain  # noqa: E402
from orchestrator.campaign import (LinearRunner, MasterRunner, load_campaign,  # noqa: E402
                                   run_uncertainty, run_wheel_sweeps)
from orchestrator.experiments import eos  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=20)
    ap.add_argument("--fmu-dir", default="fmus")
    ap.add_argument("--workers", type=int, default=2, help="Monte Carlo worker processes")
    ap.add_argument("--repeat", type=int, default=3,
                    help="sweeps from scratch, each on a fresh runner")
    args = ap.parse_args(argv)
    if args.samples < 20:
        ap.error(f"--samples is {args.samples}; give at least 20: the per-sample cost is the "
                 "slope between a quarter of the samples and all of them, and below 20 the "
                 "workers' start-up swamps it (8 samples gave a negative slope)")
    warnings.simplefilter("ignore")
    fmu_dir = eos.ensure_fmus(args.fmu_dir)
    budget = load_campaign(eos.CAMPAIGN)
    sweep = load_campaign(eos.CAMPAIGN.parent / "eos_rwa_sweep.toml")
    with tempfile.TemporaryDirectory(prefix="bench-analyses-") as tmp:
        tmp = Path(tmp)
        # the alternative's unit: one co-simulated case
        rwa = next(c for c in budget.cases if c.event == "RWA")
        master = MasterRunner(budget.scenario_dir, fmu_dir=fmu_dir)
        master(rwa.scenario, tmp / "warm")
        t0 = time.perf_counter()
        master(rwa.scenario, tmp / "one")
        t_case = time.perf_counter() - t0

        scratch = []
        for i in range(max(1, args.repeat)):
            runner = LinearRunner(sweep.scenario_dir, fmu_dir=fmu_dir)
            for sw in sweep.wheel_sweeps:
                runner.compiled(sw["scenario"])      # the model build
            t0 = time.perf_counter()
            run_wheel_sweeps(sweep, tmp / f"sweep{i}", runner)
            scratch.append(time.perf_counter() - t0)
        t_sweep = float(np.median(scratch))
        # again on the same loops: their open-ACS loops and factorisations are kept,
        # what a second range, wheel or metric on a configuration costs
        t0 = time.perf_counter()
        run_wheel_sweeps(sweep, tmp / "sweep2", runner)
        t_again = time.perf_counter() - t0

        items = (Uncertain("frequency", "modal_frequency",
                           Distribution("uniform", 0.95, 1.05), per_mode=True),
                 Uncertain("damping", "modal_damping", Distribution("uniform", 0.5, 2.0),
                           per_mode=True),
                 Uncertain("amplitude", "amplitude", Distribution("uniform", 0.8, 1.2),
                           instances=tuple(sorted(n for n in budget.cases[0].scenario["fmus"]
                                                  if n.startswith("dist_")))))
        lrun = LinearRunner(budget.scenario_dir, fmu_dir=fmu_dir)
        timings = {}
        for n in (max(2, args.samples // 4), args.samples):
            camp = dataclasses.replace(budget, uncertainty={
                "samples": n, "seed": 1, "confidence": (0.95,), "parameters": items})
            (tmp / f"mc{n}").mkdir()
            t0 = time.perf_counter()
            run_uncertainty(camp, tmp / f"mc{n}", lrun, progress=False, workers=args.workers)
            timings[n] = (time.perf_counter() - t0, peak_rss_mb())
    n1, n2 = sorted(timings)
    per_sample = (timings[n2][0] - timings[n1][0]) / (n2 - n1)
    setup = timings[n1][0] - n1 * per_sample
    print(f"one co-simulated EOS case (8 s at 1 kHz, native FMUs): {t_case:.2f} s")
    print(f"{'analysis':<48}{'linear (s)':>12}{'co-simulation (s)':>20}")
    print(f"{'RWA sweep, 500 speeds x 15 axes x 2 configs':<48}{t_sweep:>12.2f}"
          f"{2 * 500 * t_case:>20.0f}  (500 cases per configuration, estimated)")
    if len(scratch) > 1:
        print(f"  (median of {len(scratch)} from scratch, {min(scratch):.2f}-"
              f"{max(scratch):.2f} s)")
    print(f"{'  the same again, loops kept (per-speed work only)':<48}{t_again:>12.2f}")
    print(f"{f'Monte Carlo, per sample (24 records), {args.workers} workers':<48}{per_sample:>12.2f}"
          f"{24 * t_case:>20.1f}")
    print(f"{'Monte Carlo, 1000 samples (extrapolated)':<48}{setup + 1000 * per_sample:>12.0f}"
          f"{24000 * t_case:>20.0f}")
    # the slope can undercount (a measured 1000-sample campaign took 236 s where it said
    # 154 s): the whole run's rate, set-up included, beside it
    whole = timings[n2][0] / n2
    print(f"{f'  the {n2}-sample run as a whole, per sample':<48}{whole:>12.2f}"
          f"   (1000 at that rate: {1000 * whole:.0f} s)")
    print(f"peak memory: {timings[n1][1]:.0f} MB after {n1} samples, {timings[n2][1]:.0f} MB "
          f"after {n2}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
