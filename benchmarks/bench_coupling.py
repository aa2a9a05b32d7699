"""The piezo FMUs' two couplings side by side: what the step-mean force costs.

``coupling = 1`` (the default) computes the amplifier's mean force over the coming step
whenever ``v_cmd`` is set and after every step, besides the step itself; ``coupling = 0``
(the force at the end of the last step) only steps.  Both run the ten-bay closed loop
(``scenarios/truss10_closed_loop.toml``, six FMUs, 12 s at 1 ms, two piezo FMUs) and one
EOS budget case (``scenarios/eos_budget_all_legs.toml``, fifteen piezo FMUs, isolation on,
3 s) with the master in this process, native FMUs, best of ``--repeat`` runs; the Python
twins once each on the ten-bay loop.

Run:  .venv/bin/python benchmarks/bench_coupling.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TRUSS = ROOT / "scenarios" / "truss10_closed_loop.toml"
EOS = ROOT / "scenarios" / "eos_budget_all_legs.toml"
LEGS = [f"{m}_mount{i}" for m in ("swir", "vnir") for i in range(1, 7)]


def _overrides(scenario, coupling):
    if scenario == TRUSS:
        return {f"piezo_{m}.coupling": coupling for m in ("diag", "long")}
    ov = {f"piezo_iso{i}.coupling": coupling for i in (1, 2, 3)}
    ov.update({f"piezo_{leg}.coupling": coupling for leg in LEGS})
    ov.update({"ctrl_iso1.gain": 0.262, "ctrl_iso2.gain": -0.105, "ctrl_iso3.gain": 1.049,
               "dist_swir.preset": "swir_cryocooler"})
    ov.update({f"ctrl_{leg}.gain": 1.0 for leg in LEGS})
    return ov


def _time(scenario, coupling, stop, fmu_dir, kind, repeat):
    from orchestrator import run_scenario

    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            run_scenario(scenario, stop_time=stop, overrides=_overrides(scenario, coupling),
                         fmu_dir=fmu_dir, fmu_kind=kind)
        best = min(best, time.perf_counter() - t0)
    return best


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    from fmutools.ensure import ensure_fmus
    from orchestrator.experiments import eos
    from orchestrator.experiments.truss_decay import FMUS

    with tempfile.TemporaryDirectory(prefix="bench-coupling-") as tmp:
        fdir = Path(tmp)
        ensure_fmus(FMUS, fdir, kind="native")
        ensure_fmus(FMUS, fdir, kind="python")
        eos.ensure_fmus(fdir, kind="native")   # with the all-legs structure
        print(f"{'case':<34} {'build':<7} {'coupling 0 (s)':>15} {'coupling 1 (s)':>15} "
              f"{'ratio':>6}")
        for name, sc, stop, kind, rep in (
                ("ten-bay closed loop, 12 s", TRUSS, 12.0, "native", args.repeat),
                ("ten-bay closed loop, 12 s", TRUSS, 12.0, "python", 1),
                ("EOS case, 15 piezo loops, 3 s", EOS, 3.0, "native", args.repeat)):
            t0 = _time(sc, 0, stop, fdir, kind, rep)
            t1 = _time(sc, 1, stop, fdir, kind, rep)
            print(f"{name:<34} {kind:<7} {t0:15.2f} {t1:15.2f} {t1 / t0:6.2f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
