"""Checks of a big scenario: the linear checks next to the quadratic ones they replace.

Run::

    .venv/bin/python benchmarks/bench_scenario_checks.py [--sizes 2000 20000]

For each size n, side by side in one run:

* ``duplicates``: the recorded-variable duplicate check over n names with one repeat,
  as :func:`orchestrator.scenario.model.duplicates` does it (one pass with a set) and
  as it was done before (``[v for v in names if names.count(v) > 1]``, O(n^2));
* ``step_groups``: the Gauss-Seidel step order of n instances chained in the reverse
  of their declaration order (every group waits for the one declared after it), as
  :func:`orchestrator.cosim.graph.step_groups` does it (Kahn's algorithm with a heap)
  and as it was done before (a scan of every component for the next ready one, O(n^2):
  the tests' definition of the order, ``tests/orchestrator/test_graph.py``);
* ``read_toml``: a whole TOML scenario of n instances, n connections (each to the last
  instance, the worst case of a list lookup) and n recorded variables, read and checked
  by :func:`orchestrator.scenario.read_toml`; its file size is printed, and its time
  should grow in proportion to n.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path


def best(fn, repeat: int = 3) -> float:
    """Best wall time of ``fn()`` over ``repeat`` runs (s)."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def scenario_text(n: int) -> str:
    """n instances, n connections to the last one, n recorded variables."""
    head = "[experiment]\nstop = 1\noutput_interval = 0.1\n"
    fmus = "".join(f'[fmus.a{i}]\nfmu = "x"\nperiod = 0.1\n' for i in range(n))
    last = f"a{n - 1}"
    conns = "".join(f'[[connections]]\nfrom = "a{i}.y"\nto = "{last}.u{i}"\n'
                    for i in range(n))
    rec = ", ".join(f'"a{i}.y"' for i in range(n))
    return head + fmus + conns + f"[record]\nvariables = [{rec}]\n"


def main() -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # the tests' oracle
    from orchestrator.cosim.graph import step_groups
    from orchestrator.scenario import Connection, read_toml
    from orchestrator.scenario.model import duplicates
    from tests.orchestrator.test_graph import reference_order as quadratic_order

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[2000, 20000])
    args = ap.parse_args()
    print(f"{'n':>7} {'case':<28} {'linear (s)':>11} {'quadratic (s)':>14} {'file':>9}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.sizes:
            names = [f"a.v{i}" for i in range(n)] + ["a.v1"]
            lin = best(lambda names=names: duplicates(names))
            quad = best(lambda names=names: [v for v in names if names.count(v) > 1],
                        repeat=1)
            assert duplicates(names) == ["a.v1"]
            print(f"{n:>7} {'duplicates':<28} {lin:>11.4f} {quad:>14.3f} {'':>9}")
            names = [f"i{k}" for k in range(n)]
            pairs = list(zip(names[1:], names[:-1]))
            edges = [Connection(b, "y", a, "u") for b, a in pairs]
            lin = best(lambda names=names, edges=edges: step_groups(names, edges))
            quad = best(lambda names=names, pairs=pairs: quadratic_order(names, pairs),
                        repeat=1)
            assert step_groups(names, edges)[0] == quadratic_order(names, pairs)
            print(f"{n:>7} {'step_groups':<28} {lin:>11.4f} {quad:>14.3f} {'':>9}")
            path = Path(tmp) / f"s{n}.toml"
            path.write_text(scenario_text(n))
            t = best(lambda path=path: read_toml(path), repeat=1)
            size = f"{path.stat().st_size / 2**20:.1f} MiB"
            print(f"{n:>7} {'read_toml (whole scenario)':<28} {t:>11.3f} {'':>14} {size:>9}")


if __name__ == "__main__":
    main()
