"""NASTRAN import (BDF + OP4) next to the native reduction, on a big lattice tower.

Run::

    .venv/bin/python benchmarks/bench_nastran.py [--dofs 100000] [--section 10] [--modes 100]
        [--threads 1] [--keep DIR]

The tower of ``benchmarks/bench_reduction.py`` (:func:`structfmu.models.tower.build`,
``section x section`` nodes per plane, 4 piezo active members in the first bay) is written
once as a BDF plus an ASCII OP4 of KGG and MGG with
:func:`structfmu.nastran.write_truss_deck` (timed, not part of the comparison).  Then each
case runs in a fresh Python subprocess, so its peak memory (``VmHWM``) is its own:

* ``native reduce``: ``tower.build`` + :func:`structfmu.reduce.reduce` to ``--modes``
  eigenvectors plus 4 Gram-Schmidt Ritz vectors (what ``bench_reduction.py`` times);
* ``import: BDF only`` / ``import: OP4 only``: :func:`structfmu.nastran.read_deck` and
  :func:`structfmu.nastran.read_matrices` alone (pyNastran's readers), for the breakdown;
* ``import + reduce``: :func:`structfmu.nastran.import_nastran` with the 4 stacks
  (``--actuator EID=P-243.30``), the same modes and Ritz vectors through the same
  :func:`structfmu.reduce.reduce_matrices`.

BLAS threads are set by ``--threads`` (default 1: ARPACK's small BLAS-2 calls lose to thread
hand-offs, see benchmarks/README.md).  The lowest eigenvalues of the two paths are compared.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from _measure import cpu_s, emit, peak_rss_mb, run_worker

def worker(case: str, n_bays: int, section: int, modes: int, deck: str) -> dict:
    """Run one case in this process and return its measurements."""
    from structfmu import nastran
    from structfmu.models import tower
    from structfmu.reduce import reduce

    cpu0 = cpu_s()
    t0 = time.perf_counter()
    out = {"case": case}
    bdf, op4 = Path(deck) / "tower.bdf", Path(deck) / "tower.op4"
    if case == "native":
        truss = tower.build(n_bays, section, section)
        model = reduce(truss, modes)
        out["n_dof"] = int(model.meta["n_free"])
    elif case == "bdf":
        d = nastran.read_deck(bdf, "SI")
        out["n_dof"] = 6 * len(d.grids)
    elif case == "op4":
        d = nastran.read_deck(bdf, "SI")  # the DOF map needs the grids (cheap next to OP4)
        t0 = time.perf_counter()
        cpu0 = cpu_s()
        K, _ = nastran.read_matrices(op4, nastran._gset(d), "SI")
        out["n_dof"] = int(K.shape[0])
    else:
        truss = tower.build(n_bays, section, section)  # only for the actuator ids
        acts = [nastran.parse_actuator(f"{a.element + 1}=P-243.30,name={a.name}", "SI")
                for a in truss.active]
        del truss
        t0 = time.perf_counter()
        cpu0 = cpu_s()
        model = nastran.import_nastran(bdf, units="SI", op4=op4, n_modes=modes,
                                       actuators=acts, ritz="actuators")
        out["n_dof"] = int(model.meta["n_free"])
    if case in ("native", "import"):
        out.update(n_ritz=model.n_ritz, lam=(model.omega**2).tolist())
    out.update(wall=time.perf_counter() - t0, cpu=cpu_s() - cpu0, peak_mb=peak_rss_mb())
    return out


def run_case(case, n_bays, section, modes, deck, threads) -> dict:
    """Run ``worker`` for one case in a fresh subprocess."""
    return run_worker(__file__, ["--worker", case, "--bays", str(n_bays), "--section",
                                 str(section), "--modes", str(modes), "--deck", deck],
                      case, threads)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dofs", type=int, default=100_000)
    p.add_argument("--section", type=int, default=10, help="nodes per side of a plane")
    p.add_argument("--modes", type=int, default=100)
    p.add_argument("--threads", type=int, default=1, help="BLAS threads of each worker")
    p.add_argument("--keep", default=None, help="write the deck here and keep it")
    p.add_argument("--worker", help=argparse.SUPPRESS)
    p.add_argument("--bays", type=int, help=argparse.SUPPRESS)
    p.add_argument("--deck", help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.worker:
        emit(worker(a.worker, a.bays, a.section, a.modes, a.deck))
        return

    import numpy as np

    from structfmu import nastran
    from structfmu.models import tower

    s = a.section
    n_bays = tower.bays_for(a.dofs, s, s)
    with tempfile.TemporaryDirectory() as tmp:
        deck = Path(a.keep or tmp)
        deck.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        truss = tower.build(n_bays, s, s)
        nastran.write_truss_deck(truss, deck / "tower.bdf", deck / "tower.op4")
        t_write = time.perf_counter() - t0
        sizes = {f: (deck / f).stat().st_size / 2**20 for f in ("tower.bdf", "tower.op4")}
        print(f"tower {s} x {s} nodes per plane, {n_bays} bays, {truss.n_dof} DOF, "
              f"{len(truss.elements)} rods; {a.modes} modes + 4 Ritz vectors; BLAS threads "
              f"{a.threads}; {os.cpu_count()} CPUs; one fresh subprocess per case", flush=True)
        print(f"deck written in {t_write:.1f} s: tower.bdf {sizes['tower.bdf']:.0f} MB, "
              f"tower.op4 (ASCII, KGG + MGG) {sizes['tower.op4']:.0f} MB", flush=True)
        del truss
        rows = []
        for case, label in (("native", "native reduce"), ("bdf", "import: BDF only"),
                            ("op4", "import: OP4 only"), ("import", "import + reduce")):
            res = run_case(case, n_bays, s, a.modes, str(deck), a.threads)
            res["label"] = label
            rows.append(res)
            print(f"  {label}: {res['wall']:.1f} s", flush=True)
    head = f"{'case':<18} {'DOF':>8} {'wall s':>8} {'CPU s':>8} {'peak MB':>8}"
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['label']:<18} {r['n_dof']:>8} {r['wall']:8.1f} {r['cpu']:8.1f} "
              f"{r['peak_mb']:8.0f}")
    by = {r["case"]: r for r in rows}
    lam0, lam1 = np.array(by["native"]["lam"]), np.array(by["import"]["lam"])
    flex = lam0 > 0
    print(f"import vs native: max relative eigenvalue difference "
          f"{np.max(np.abs(lam1[flex] - lam0[flex]) / lam0[flex]):.1e} over {flex.sum()} modes")


if __name__ == "__main__":
    main()
