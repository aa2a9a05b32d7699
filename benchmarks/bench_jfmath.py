"""Cost per call of the native FMUs' own transcendental functions against the C library's,
side by side in one run.

``src/nativefmu/csrc/jfmath.c`` (the same bits on every platform, within 1 ulp) and glibc's
``sin``, ``cos``, ``tan``, ``exp``, ``expm1``, ``log``, ``log1p`` are called on the same
arguments in one C program compiled with the FMUs' flags (``-O2 -ffp-contract=off``):
trigonometric arguments in [-7, 7] (one reduction step) and [-1e5, 1e5] (the disturbance's
phases), exp's in [-50, 50], log's in [1e-3, 1e3].  Each time is the best of ``--repeat``
loops of ``--calls`` calls (ns per call); the sums the loops print keep the calls alive.

Run:  .venv/bin/python benchmarks/bench_jfmath.py [--calls 2000000] [--repeat 5]
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CSRC = REPO / "src" / "nativefmu" / "csrc"

DRIVER = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "jfmath.h"
static double now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t);
                          return t.tv_sec + 1e-9 * t.tv_nsec; }
#define BENCH(label, f, lo, hi) do { \
    double best = 1e300, s = 0.0; int r; long i; \
    for (r = 0; r < repeat; r++) { double t0 = now(); \
        for (i = 0; i < n; i++) s += f(lo + (hi - lo) * ((double)i / n)); \
        if (now() - t0 < best) best = now() - t0; } \
    printf("%s %.2f %g\n", label, 1e9 * best / n, s); } while (0)
int main(int argc, char **argv) {
    long n = atol(argv[1]); int repeat = atoi(argv[2]); (void)argc;
    BENCH("ours sin [-7,7]", jm_sin, -7.0, 7.0);      BENCH("libm sin [-7,7]", sin, -7.0, 7.0);
    BENCH("ours sin [-1e5,1e5]", jm_sin, -1e5, 1e5);  BENCH("libm sin [-1e5,1e5]", sin, -1e5, 1e5);
    BENCH("ours cos [-7,7]", jm_cos, -7.0, 7.0);      BENCH("libm cos [-7,7]", cos, -7.0, 7.0);
    BENCH("ours tan [-7,7]", jm_tan, -7.0, 7.0);      BENCH("libm tan [-7,7]", tan, -7.0, 7.0);
    BENCH("ours exp [-50,50]", jm_exp, -50.0, 50.0);  BENCH("libm exp [-50,50]", exp, -50.0, 50.0);
    BENCH("ours expm1 [-1,1]", jm_expm1, -1.0, 1.0);  BENCH("libm expm1 [-1,1]", expm1, -1.0, 1.0);
    BENCH("ours log [1e-3,1e3]", jm_log, 1e-3, 1e3);  BENCH("libm log [1e-3,1e3]", log, 1e-3, 1e3);
    BENCH("ours log1p [-0.5,10]", jm_log1p, -0.5, 10.0);
    BENCH("libm log1p [-0.5,10]", log1p, -0.5, 10.0);
    return 0;
}
"""


def main() -> None:
    """Compile the driver, run it, print one row per function and range."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=2_000_000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_jfmath_") as tmp:
        src, exe = Path(tmp) / "bench.c", Path(tmp) / "bench"
        src.write_text(DRIVER)
        subprocess.run(["gcc", "-std=c99", "-O2", "-ffp-contract=off", "-fno-fast-math",
                        "-D_POSIX_C_SOURCE=199309L", "-I", str(CSRC), "-o", str(exe),
                        str(src), str(CSRC / "jfmath.c"), "-lm"], check=True)
        out = subprocess.run([str(exe), str(args.calls), str(args.repeat)], check=True,
                             capture_output=True, text=True).stdout
    rows = {}
    for line in out.splitlines():
        who, name, rng, ns, _ = line.split()
        rows.setdefault((name, rng), {})[who] = float(ns)
    print(f"{'function':<8} {'arguments':<14} {'ours (ns)':>10} {'libm (ns)':>10} {'ratio':>6}")
    for (name, rng), t in rows.items():
        print(f"{name:<8} {rng:<14} {t['ours']:>10.2f} {t['libm']:>10.2f} "
              f"{t['ours'] / t['libm']:>6.2f}")


if __name__ == "__main__":
    main()
