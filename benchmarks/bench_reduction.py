"""Model reduction of big lattice towers: sparse shift-invert Lanczos vs dense eigh.

Run::

    .venv/bin/python benchmarks/bench_reduction.py [--big-dofs 100000] [--small-dofs 3900]
        [--section 10] [--modes 100] [--profile]

Each case runs in a fresh Python subprocess, so its peak memory (``VmHWM`` of
``/proc/self/status``, read by the worker at its end) is its own.  Cases:

* ``sparse reduce``: :func:`structfmu.models.tower.build`, then
  :func:`structfmu.reduce.reduce` to ``--modes`` eigenvectors plus one static Ritz vector
  per active member (4), on the big and on the small tower.  ``reduce`` assembles the
  matrices itself; the assembly is also timed on its own (``assemble`` column) and is
  included in the ``reduce`` time.
* ``dense eigh all`` / ``dense eigh N``: the dense matrices ``K.toarray()``,
  ``M.toarray()`` of the small tower and :func:`scipy.linalg.eigh` for every eigenpair /
  for the lowest ``--modes`` only (``subset_by_index``), eigensolver time only.
* ``imports only``: the baseline memory of a worker that imports numpy, scipy and the
  package.

Both towers have the same ``section x section`` cross-section; only the number of bays
differs.  Sparse cases run twice: with the default BLAS threads and with
``OPENBLAS_NUM_THREADS=1`` (ARPACK's small BLAS-2 calls lose to thread hand-offs on a busy
machine).  The wall clock of a loaded machine overstates the cost, so the CPU time
(user + system, all threads, from ``getrusage``) of each worker is printed too.  With
``--profile`` the big sparse case runs under :mod:`cProfile` and the top functions are
printed after the table.  The lowest eigenvalues of the sparse and dense solvers on the
small tower are compared (relative difference printed).
"""

from __future__ import annotations

import argparse
import os
import time

from _measure import cpu_s, emit, peak_rss_mb, run_worker

def worker(case: str, n_bays: int, section: int, modes: int, profile: bool) -> dict:
    """Run one case in this process and return its measurements."""
    import scipy.linalg as la

    from structfmu.fem import assemble
    from structfmu.models import tower
    from structfmu.reduce import reduce

    out = {"case": case, "n_bays": n_bays}
    if case == "imports":
        out.update(n_dof=0, cpu=cpu_s(), peak_mb=peak_rss_mb())
        return out
    cpu0 = cpu_s()
    t0 = time.perf_counter()
    truss = tower.build(n_bays, section, section)
    t1 = time.perf_counter()
    K, M = assemble(truss)
    t2 = time.perf_counter()
    out.update(n_dof=int(K.shape[0]), build=t1 - t0, assemble=t2 - t1)
    if case == "sparse":
        del K, M
        prof = None
        if profile:
            import cProfile
            prof = cProfile.Profile()
            prof.enable()
        t3 = time.perf_counter()
        model = reduce(truss, modes)
        t4 = time.perf_counter()
        if prof is not None:
            import io
            import pstats
            prof.disable()
            buf = io.StringIO()
            pstats.Stats(prof, stream=buf).sort_stats("cumulative").print_stats(18)
            out["profile"] = buf.getvalue()
        out.update(solve=t4 - t3, n_ritz=model.n_ritz, lam=(model.omega**2).tolist())
    else:
        Kd, Md = K.toarray(), M.toarray()
        del K, M
        t3 = time.perf_counter()
        if case == "dense_all":
            lam = la.eigh(Kd, Md, eigvals_only=False)[0]
        else:
            lam = la.eigh(Kd, Md, subset_by_index=[0, modes - 1])[0]
        t4 = time.perf_counter()
        out.update(solve=t4 - t3, n_ritz=0, lam=lam[:modes].tolist())
    out.update(cpu=cpu_s() - cpu0, peak_mb=peak_rss_mb())
    return out


def run_case(case, n_bays, section, modes, threads=None, profile=False) -> dict:
    """Run ``worker`` for one case in a fresh subprocess (``threads``: BLAS threads)."""
    args = ["--worker", case, "--bays", str(n_bays), "--section", str(section),
            "--modes", str(modes)] + (["--profile"] if profile else [])
    res = run_worker(__file__, args, case, threads)
    res["threads"] = "default" if threads is None else str(threads)
    return res


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--big-dofs", type=int, default=100_000)
    p.add_argument("--small-dofs", type=int, default=3_900)
    p.add_argument("--section", type=int, default=10, help="nodes per side of a plane")
    p.add_argument("--modes", type=int, default=100)
    p.add_argument("--profile", action="store_true")
    p.add_argument("--skip-big", action="store_true")
    p.add_argument("--worker", help=argparse.SUPPRESS)
    p.add_argument("--bays", type=int, help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.worker:
        emit(worker(a.worker, a.bays, a.section, a.modes, a.profile))
        return

    from structfmu.models import tower

    s = a.section
    small = tower.bays_for(a.small_dofs, s, s)
    big = tower.bays_for(a.big_dofs, s, s)
    plan = [("imports", "imports only", 0, None), ("dense_all", "dense eigh all", small, None),
            ("dense_sub", f"dense eigh {a.modes}", small, None),
            ("sparse", "sparse reduce", small, None), ("sparse", "sparse reduce", small, 1)]
    if not a.skip_big:
        plan += [("sparse", "sparse reduce", big, None), ("sparse", "sparse reduce", big, 1)]
    print(f"towers {s} x {s} nodes per plane; {a.modes} modes (+4 Ritz vectors for reduce); "
          f"{os.cpu_count()} CPUs; one fresh subprocess per case", flush=True)
    rows = []
    for i, (case, label, n_bays, threads) in enumerate(plan):
        res = run_case(case, n_bays, s, a.modes, threads,
                       a.profile and not a.skip_big and i == len(plan) - 1)
        res["label"] = label
        rows.append(res)
    head = (f"{'case':<18} {'BLAS thr':>8} {'DOF':>8} {'bays':>5} {'build s':>8} "
            f"{'assemble s':>10} {'eig/reduce s':>12} {'CPU s':>7} {'peak MB':>8}")
    print(head)
    print("-" * len(head))
    for r in rows:
        if r["case"] == "imports":
            print(f"{r['label']:<18} {r['threads']:>8} {'-':>8} {'-':>5} {'-':>8} {'-':>10} "
                  f"{'-':>12} {r['cpu']:7.1f} {r['peak_mb']:8.0f}")
            continue
        print(f"{r['label']:<18} {r['threads']:>8} {r['n_dof']:>8} {r['n_bays']:>5} "
              f"{r['build']:8.2f} {r['assemble']:10.2f} {r['solve']:12.2f} {r['cpu']:7.1f} "
              f"{r['peak_mb']:8.0f}")
    import numpy as np

    small_rows = {r["case"]: r for r in rows if r.get("n_bays") == small}  # last of each
    ref = np.array(small_rows["dense_sub"]["lam"])
    for key in ("dense_all", "sparse"):
        lam = np.array(small_rows[key]["lam"])
        print(f"small tower, {key} vs dense eigh {a.modes}: max relative eigenvalue difference "
              f"{np.max(np.abs(lam - ref) / ref):.1e}")
    for big_row in ([] if a.skip_big else rows[-2:]):
        ok = big_row["solve"] < 60 and big_row["peak_mb"] < 4096
        print(f"goal (< 60 s and < 4 GB for {big_row['n_dof']} DOF, BLAS threads "
              f"{big_row['threads']}): {'met' if ok else 'NOT met'} (reduce wall "
              f"{big_row['solve']:.1f} s, worker CPU {big_row['cpu']:.1f} s, peak "
              f"{big_row['peak_mb'] / 1024:.2f} GB)")
        if "profile" in big_row:
            print("\ncProfile of the big sparse case (cumulative):")
            print(big_row["profile"])


if __name__ == "__main__":
    main()
