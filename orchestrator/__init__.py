"""jitterfmu's front door: scenarios in, co-simulated jitter out.

The pipeline, on the ten-bay truss closed loop (the FMUs come from ``jitterfmu build``;
``fmu_dir`` is their folder):

>>> from orchestrator import load_scenario, prepare, run_scenario
>>> scenario = load_scenario("scenarios/truss10_closed_loop.toml")
>>> [i.name for i in scenario.instances]
['structure', 'piezo_diag', 'piezo_long', 'ctrl_diag', 'ctrl_long', 'excitation']
>>> plan = prepare(scenario, fmu_dir)            # checked against the FMUs, nothing runs
>>> plan.groups[:3]       # step order: a feedthrough source before the sinks it feeds
[('ctrl_diag',), ('piezo_diag',), ('ctrl_long',)]
>>> result = run_scenario(scenario, stop_time=0.2, fmu_dir=fmu_dir)
>>> float(result.table["time"][-1]), result.metadata["status"]
(0.2, 'ok')
>>> round(float(abs(result.table["structure.strain_diag"]).max()), 9) > 0
True

What each room holds, in pipeline order:

* :mod:`orchestrator.scenario` -- the scenario model, TOML and SSP read/write;
* :mod:`orchestrator.cosim` -- the engine: FMU information, the checked plan, the
  feedthrough graph, FMU instances, the bus, the schedule and :class:`Simulation`;
* :mod:`orchestrator.run` -- :func:`run_scenario`: a run with its output folder;
* :mod:`orchestrator.results` -- the recorded table and ``run.json``;
* :mod:`orchestrator.campaign` -- disturbance campaigns (cases, pool or Dask, summary);
* :mod:`orchestrator.metrics`, :mod:`orchestrator.report` -- jitter metrics, reports;
* :mod:`orchestrator.analysis` -- the linear closed loop of a scenario (poles, margins,
  upper bounds); :mod:`orchestrator.reference` -- its sampled-data reference (the
  continuous structure and amplifiers: what the partition adds to each loop);
  :mod:`orchestrator.experiments` -- the paper's experiments;
* :mod:`orchestrator.cli` -- the ``jitterfmu`` command.

The campaign API (``load_campaign``, ``run_campaign``, ``MasterRunner``) is exported
here too; it is imported on first use, since the metrics it computes load scipy.
"""

from __future__ import annotations

from .cosim import (
    DivergenceError,
    EarlyEndWarning,
    JacobiLoopWarning,
    SaturationWarning,
    Plan,
    Simulation,
    SimulationError,
    TimebaseWarning,
    UnconnectedInputWarning,
    prepare,
)
from .results import RunResult, read_table
from .run import OutputError, run_scenario
from .scenario import Scenario, ScenarioError, load_scenario, read_ssp, write_ssp

__all__ = [
    "load_scenario",
    "Scenario",
    "ScenarioError",
    "prepare",
    "Plan",
    "Simulation",
    "SimulationError",
    "run_scenario",
    "RunResult",
    "read_table",
    "OutputError",
    "read_ssp",
    "write_ssp",
    "UnconnectedInputWarning",
    "TimebaseWarning",
    "JacobiLoopWarning",
    "EarlyEndWarning",
    "DivergenceError",
    "SaturationWarning",
    "load_campaign",
    "run_campaign",
    "MasterRunner",
]

_CAMPAIGN_API = ("load_campaign", "run_campaign", "MasterRunner")


def __getattr__(name):
    # the campaign API is loaded on first use: its metrics import scipy (about 2 s)
    if name in _CAMPAIGN_API:
        from . import campaign

        return getattr(campaign, name)
    raise AttributeError(f"module 'orchestrator' has no attribute {name!r}")
