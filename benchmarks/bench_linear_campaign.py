"""The EOS 24-case budget: co-simulated campaign vs the linear engine, side by side.

Run::

    .venv/bin/python benchmarks/bench_linear_campaign.py [--workers 2] [--repeat 3]

Both engines run ``campaigns/eos_budget.toml`` (12 events x isolation off/on, 8 s at
1 kHz, the 10 Hz ACS and fifteen piezo loops) from empty folders, FMUs built.  The
co-simulation uses ``--workers`` processes; the linear engine runs in this process.  Its
time is split into the closing of the two configurations' loops (``linearize`` and
compiling the runs, once per configuration: the "model build") and the 24 cases
themselves (every case's record, metrics, files and summary), ``--repeat`` times on a
fresh runner each (the median printed, and the range).  The build is timed twice in
each repeat: with the store of built blocks off (every block from its FMU) and on,
filled by an earlier build (:mod:`orchestrator.analysis.blockstore`, what a second
command on the same FMUs finds).  The campaign is also timed whole, as the command runs
it (a fresh runner building inside its threads, each configuration's loop at once while
the other threads run the cases whose loop is built), store off and on, with the CPU
time of the process (store off): divided by the cores, the wall time no schedule can go
under.  Every summary cell of the two engines is compared, for every linear run.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from orchestrator import linearcheck
from orchestrator.analysis import scenario as lin_scenario
from orchestrator.campaign import LinearRunner, MasterRunner, load_campaign, run_campaign
from orchestrator.experiments import eos


def _summary(folder):
    return {(r["case"], r["instrument"], r["axis"], r["metric"], r["window"]): r["value"]
            for r in pq.read_table(Path(folder) / "summary.parquet").to_pylist()}


def _largest_difference(a: dict, folder) -> float:
    """The largest relative difference of a summary cell of ``folder`` from ``a``."""
    b = _summary(folder)
    return max(abs(a[k] - b[k]) / abs(a[k]) for k in a if a[k])


def _spread(times) -> str:
    """``min-max`` of repeated timings, or nothing for one."""
    return f"{min(times):.2f}-{max(times):.2f}" if len(times) > 1 else ""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--fmu-dir", default="fmus")
    ap.add_argument("--repeat", type=int, default=3,
                    help="linear runs, each on a fresh runner (build and cases)")
    args = ap.parse_args(argv)
    fmu_dir = eos.ensure_fmus(args.fmu_dir)
    camp = load_campaign(eos.CAMPAIGN)
    with tempfile.TemporaryDirectory(prefix="bench-linear-") as tmp:
        tmp = Path(tmp)
        t0 = time.perf_counter()
        co = run_campaign(camp, tmp / "cosim", MasterRunner(camp.scenario_dir, fmu_dir=fmu_dir),
                          workers=args.workers, progress=False)
        t_co = time.perf_counter() - t0

        builds, stored, cases, worst = [], [], [], 0.0
        a = _summary(tmp / "cosim")
        configs = {c.configuration: c for c in camp.cases}

        def fresh(store: str):
            # nothing this process kept from the previous build (its FMU extractions and
            # blocks, its loops' stability verdicts); the store of built blocks off
            # (every block from its FMU) or on (blocks an earlier process kept)
            os.environ["JITTERFMU_BLOCK_CACHE"] = store
            lin_scenario._EXTRACTED.clear()
            linearcheck._VERDICTS.clear()
            linearcheck._SOURCES.clear()
            return LinearRunner(camp.scenario_dir, fmu_dir=fmu_dir)

        def build(store: str):
            runner = fresh(store)
            t0 = time.perf_counter()
            for case in configs.values():   # the model build: one closed loop each
                runner.compiled(case.scenario)
            return runner, time.perf_counter() - t0

        build("on")   # the store filled, as by an earlier command on these FMUs
        wholes, wholes_on = [], []
        for i in range(max(1, args.repeat)):
            # the campaign as a command runs it: a fresh runner builds inside, on threads
            # (each configuration's loop at once), store off and then on
            for store, out in (("off", wholes), ("on", wholes_on)):
                c0, t0 = time.process_time(), time.perf_counter()
                run_campaign(dataclasses.replace(camp, engine="linear"),
                             tmp / f"whole{i}{store}", fresh(store), progress=False)
                out.append((time.perf_counter() - t0, time.process_time() - c0))
                worst = max(worst, _largest_difference(a, tmp / f"whole{i}{store}"))
            runner, t = build("off")
            builds.append(t)
            runner, t = build("on")
            stored.append(t)
            t0 = time.perf_counter()
            li = run_campaign(dataclasses.replace(camp, engine="linear"), tmp / f"linear{i}",
                              runner, progress=False)
            cases.append(time.perf_counter() - t0)
            worst = max(worst, _largest_difference(a, tmp / f"linear{i}"))
        t_build, t_li = float(np.median(builds)), float(np.median(cases))
        t_stored = float(np.median(stored))
        fr = next(iter(runner._compiled.values()))
        mem = sum(t.O.nbytes + t.ML.nbytes + sum(P.nbytes for P in t.powers)
                  + sum(g.nbytes + h.nbytes for g, h in t.cols.values())
                  for t in fr._types.values()) / 2**20
    n = len(camp.cases)
    print(f"EOS budget, {n} cases, 8 s at 1 kHz; failed: cosim {co.n_failed}, "
          f"linear {li.n_failed}")
    print(f"{'engine':<44}{'wall (s)':>10}{'per case (ms)':>15}")
    print(f"{f'co-simulation, {args.workers} workers':<44}{t_co:>10.2f}{1e3 * t_co / n:>15.1f}")
    print(f"{'linear: closing 2 configurations (build)':<44}{t_build:>10.2f}"
          f"{'':>15}  {_spread(builds)}")
    print(f"{'  the same, blocks read from the store':<44}{t_stored:>10.2f}"
          f"{'':>15}  {_spread(stored)}")
    print(f"{'linear: the 24 cases (records, metrics, files)':<44}{t_li:>10.2f}"
          f"{1e3 * t_li / n:>15.1f}  {_spread(cases)}")
    print(f"{'linear: total':<44}{t_build + t_li:>10.2f}")
    walls, cpus = zip(*wholes)
    walls_on = [w for w, _ in wholes_on]
    print(f"{'linear: the campaign from a fresh runner':<44}{float(np.median(walls)):>10.2f}"
          f"{'':>15}  {_spread(walls)}")
    print(f"{'  the same, blocks read from the store':<44}{float(np.median(walls_on)):>10.2f}"
          f"{'':>15}  {_spread(walls_on)}")
    cores = os.cpu_count() or 1
    spread = f" ({_spread(cpus)})" if len(cpus) > 1 else ""
    print(f"  its CPU time {float(np.median(cpus)):.2f} s{spread}: on {cores} "
          f"cores no schedule runs it in under {float(np.median(cpus)) / cores:.2f} s; "
          f"10x the co-simulation is {t_co / 10:.2f} s")
    print(f"(linear rows: the median of {len(cases)} runs on fresh runners)")
    print(f"speed-up of the cases: {t_co / t_li:.0f}x, with the build: "
          f"{t_co / (t_build + t_li):.1f}x, with the build from stored blocks: "
          f"{t_co / (t_stored + t_li):.1f}x")
    print(f"speed-up of the whole campaign (a fresh runner, as the command): "
          f"{t_co / float(np.median(walls)):.1f}x, from stored blocks: "
          f"{t_co / float(np.median(walls_on)):.1f}x")
    print(f"largest relative difference of a summary cell: {worst:.1e} "
          f"({len(a)} cells)")
    print(f"memory state {fr.n_memory} of {fr.lin.n}; run matrices of one configuration: "
          f"{mem:.0f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
