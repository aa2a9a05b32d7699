"""Windowed peak-to-peak jitter: O(N) running extrema vs a brute-force sliding window.

Run::

    .venv/bin/python benchmarks/bench_jitter.py [--samples 10000000]

For each window (10, 1e3 and 1e5 samples) the fast path (``orchestrator.metrics.peak_to_peak``,
scipy running max/min) runs on the whole record; the brute force (numpy stride tricks,
``sliding_window_view(x, n).max(-1) - ...min(-1)``, O(N n)) runs on the whole record when
``N n`` is at most ``--brute-budget`` element visits and otherwise on a prefix slice sized to
that budget, its time extrapolated linearly in the number of windows (marked "extrap.").
Both results are compared on the slice the brute force ran on.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _measure import best_of  # noqa: E402

import numpy as np  # noqa: E402
from numpy.lib.stride_tricks import sliding_window_view  # noqa: E402

from orchestrator.metrics import peak_to_peak  # noqa: E402


def brute(x, n):
    v = sliding_window_view(x, n)
    return float((v.max(axis=-1) - v.min(axis=-1)).max())


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--samples", type=float, default=1e7)
    p.add_argument("--windows", type=float, nargs="+", default=[10, 1e3, 1e5])
    p.add_argument("--brute-budget", type=float, default=1.2e10,
                   help="max element visits for the brute force before slicing")
    p.add_argument("--repeat", type=int, default=3)
    a = p.parse_args(argv)
    n_total = int(a.samples)
    x = np.cumsum(np.random.default_rng(0).normal(size=n_total))
    print(f"record: {n_total:.3g} samples (random walk, float64); best of {a.repeat} runs")
    print(f"{'window':>8} {'fast (s)':>10} {'brute (s)':>12} {'speed-up':>9}  note")
    for w in a.windows:
        n = int(w) + 1  # samples in a window of w intervals (dt = 1)
        t_fast, _ = best_of(lambda: peak_to_peak(x, 1.0, float(int(w))), a.repeat)
        n_slice = n_total if n_total * n <= a.brute_budget else max(
            n + 1, int(a.brute_budget // n))
        sl = x[:n_slice]
        t_b, ref = best_of(lambda: brute(sl, n), 1 if n_slice * n > 1e9 else a.repeat)
        fast_sl = peak_to_peak(sl, 1.0, float(int(w)))
        assert fast_sl == ref, (fast_sl, ref)
        note = "full record"
        if n_slice < n_total:
            t_b *= (n_total - n + 1) / (n_slice - n + 1)
            note = f"extrap. from {n_slice:.3g}-sample slice"
        print(f"{int(w):>8} {t_fast:>10.3f} {t_b:>12.2f} {t_b / t_fast:>8.0f}x  {note}")


if __name__ == "__main__":
    main()
