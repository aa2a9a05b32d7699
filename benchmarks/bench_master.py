"""Master overhead per FMU step: the Python master (fmpy) beside libcosim, same SSP.

Builds two small FMUs (bench_master_slaves.py) into a temporary folder, runs a
six-instance mixed-rate scenario (1, 2 and 4 ms; gains, a feedback loop) with both
algorithms of the Python master, exports it as SSP and runs that in libcosim, and
reports wall time per FMU step.  A bare fmpy loop (set/doStep/get on one FMU, no
master) gives the floor that the FMI calls into a Python FMU cost on their own.

Run:  .venv/bin/python benchmarks/bench_master.py [--stop 2.0]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

SLAVES = {"MtIntegrator": "bench_master_slaves:Integrator",
          "MtGain": "bench_master_slaves:Gain"}


def scenario(stop, algorithm):
    return {
        "experiment": {"stop": stop, "output_interval": 1e-3, "algorithm": algorithm},
        "fmus": {
            "ramp": {"fmu": "MtIntegrator", "period": 1e-3, "parameters": {"u": 1.0}},
            "plant": {"fmu": "MtIntegrator", "period": 1e-3},
            "plant2": {"fmu": "MtIntegrator", "period": 1e-3},
            "ctrl": {"fmu": "MtGain", "period": 4e-3, "parameters": {"k": -5.0, "b": 1.0}},
            "g2": {"fmu": "MtGain", "period": 2e-3, "parameters": {"k": 3.0}},
            "sink": {"fmu": "MtIntegrator", "period": 4e-3},
        },
        "connections": [
            {"from": "plant.x", "to": "ctrl.u", "gain": 0.5},
            {"from": "ctrl.y", "to": "plant.u"},
            {"from": "ctrl.y", "to": "plant2.u"},
            {"from": "ramp.x", "to": "g2.u"},
            {"from": "g2.y", "to": "sink.u", "gain": -1.0},
        ],
        "record": {"variables": ["plant.x", "ctrl.y", "g2.y", "sink.x"]},
    }


def fmu_steps(stop):
    per = {"ramp": 1, "plant": 1, "plant2": 1, "ctrl": 4, "g2": 2, "sink": 4}
    n = round(stop / 1e-3)
    return sum(n // p for p in per.values())


def bare_fmpy(fmu, n):
    """set/doStep/get through fmpy's own methods on one FMU: the cost floor."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bare")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    t0 = time.perf_counter()
    for k in range(n):
        s.setReal([vr["u"]], [1.0])
        s.doStep(k / 1000, 1e-3)
        s.getReal([vr["x"]])
    return (time.perf_counter() - t0) / n


def libcosim(ssp, stop):
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.WARNING)
    ex = CosimExecution.from_ssp_file(str(ssp))
    ex.add_observer(CosimObserver.create_last_value())
    t0 = time.perf_counter()
    assert ex.simulate_until(round(stop * 1e9))
    return time.perf_counter() - t0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stop", type=float, default=2.0, help="simulated time (s)")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    from fmutools.build import FmuSpec, build_fmu
    from orchestrator import Simulation, prepare
    from orchestrator.scenario import scenario_from_dict
    from orchestrator.scenario import write_ssp

    tmp = Path(tempfile.mkdtemp(prefix="bench_master_"))
    for ident, cls in SLAVES.items():
        build_fmu(FmuSpec(model_identifier=ident, slave_class=cls), tmp)
        sys.modules.pop("bench_master_slaves", None)
    steps = fmu_steps(args.stop)
    print(f"scenario: 6 instances at 1/2/4 ms, {args.stop} s simulated, "
          f"{steps} FMU steps, {round(args.stop / 1e-3)} base ticks")
    floor = min(bare_fmpy(tmp / "MtIntegrator.fmu", 20000) for _ in range(args.repeat))
    print(f"{'bare fmpy set/doStep/get (1 FMU)':42s} {1e6 * floor:7.2f} us/FMU step")
    for alg in ("gauss-seidel", "jacobi"):
        best = float("inf")
        for _ in range(args.repeat):
            sim = Simulation(prepare(scenario_from_dict(scenario(args.stop, alg)), tmp))
            try:
                sim.initialize()
                t0 = time.perf_counter()
                sim.run()
                best = min(best, time.perf_counter() - t0)
            finally:
                sim.close()
        print(f"{'jitterfmu master, ' + alg:42s} {1e6 * best / steps:7.2f} us/FMU step "
              f"({best:.3f} s)")
    ssp = write_ssp(prepare(scenario_from_dict(scenario(args.stop, "jacobi")), tmp),
                    tmp / "bench.ssp")
    best = min(libcosim(ssp, args.stop) for _ in range(args.repeat))
    print(f"{'libcosim (libcosimpy), same SSP':42s} {1e6 * best / steps:7.2f} us/FMU step "
          f"({best:.3f} s)")


if __name__ == "__main__":
    main()
