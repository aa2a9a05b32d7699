"""Campaign throughput: cases per second in this process, and with 1 and 2 worker processes.

Run::

    .venv/bin/python benchmarks/bench_campaign.py [--cases 16] [--samples 400000]

Each case runs a synthetic runner (no FMUs): white noise through a lightly damped
second-order filter for ``--samples`` steps (a stand-in for a co-simulation of the same
length), then the campaign computes peak-to-peak and RMS jitter of two LOS axes.  Every
mode starts from an empty folder; the result tables are checked to be identical.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from scipy.signal import lfilter

from orchestrator.campaign import campaign_from_dict, run_campaign


def bench_runner(scenario, out_dir):
    p = scenario["fmus"]["dist"]["parameters"]
    n, seed = int(p["samples"]), int(p["seed"])
    w = np.random.default_rng(seed).normal(size=(2, n))
    r, th = 0.999, 2 * np.pi * float(p["frequency"]) * 1e-3
    y = lfilter([1e-7], [1, -2 * r * np.cos(th), r * r], w, axis=-1)
    path = Path(out_dir) / "results.parquet"
    pq.write_table(pa.table({"time": np.arange(n) * 1e-3, "sc.pitch": y[0], "sc.yaw": y[1]}),
                   path)
    return path


def campaign(n_cases, samples):
    base = {"experiment": {"stop": samples * 1e-3, "output_interval": 1e-3},
            "fmus": {"dist": {"fmu": "d", "period": 1e-3,
                              "parameters": {"samples": samples, "seed": 0, "frequency": 1.0}}}}
    return campaign_from_dict({
        "campaign": {"name": "bench", "scenario": base},
        "events": [{"name": f"e{i}", "overrides": {"dist.seed": i,
                                                   "dist.frequency": 5.0 + i}}
                   for i in range(n_cases)],
        "instruments": [{"name": "X", "axes": {"pitch": "sc.pitch", "yaw": "sc.yaw"}}],
        "metrics": [{"kind": "peak_to_peak", "windows": [1.0]},
                    {"kind": "rms_jitter", "windows": [1.0]}],
    })


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=16)
    ap.add_argument("--samples", type=int, default=400_000)
    a = ap.parse_args(argv)
    camp = campaign(a.cases, a.samples)
    print(f"{a.cases} cases of {a.samples} samples each")
    print(f"{'mode':>22} {'wall (s)':>9} {'cases/s':>8} {'speed-up':>9}")
    ref_t, ref_tab = None, None
    for label, workers in (("in-process (0)", 0), ("1 worker process", 1),
                           ("2 worker processes", 2)):
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            res = run_campaign(camp, d, bench_runner, workers=workers, progress=False)
            wall = time.perf_counter() - t0
            tab = pq.read_table(res.summary).sort_by([("case", "ascending"),
                                                      ("axis", "ascending"),
                                                      ("metric", "ascending")])
            tab = tab.select(["case", "key", "axis", "metric", "window", "value", "share"])
        assert res.n_failed == 0
        if ref_tab is None:
            ref_t, ref_tab = wall, tab
        assert tab.equals(ref_tab), "results differ between modes"  # bit for bit
        print(f"{label:>22} {wall:>9.2f} {a.cases / wall:>8.2f} {ref_t / wall:>8.2f}x")


if __name__ == "__main__":
    main()
