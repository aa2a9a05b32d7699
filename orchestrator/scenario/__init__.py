"""Scenarios: which FMUs, at which rates, wired how, recording what.

A scenario is read from TOML (or built from a dict by a campaign) into frozen
dataclasses.  Only structure is checked here (names, signs, shapes); checks that need
the FMUs' model descriptions live in :func:`orchestrator.cosim.prepare`.

Format::

    [experiment]
    start = 0.0                   # s, optional
    stop = 10.0                   # s
    output_interval = 1e-3        # s
    algorithm = "gauss-seidel"    # or "jacobi"
    fmu_kind = "native"           # or "python": which build of the suite's FMUs

    [fmus.structure]
    fmu = "truss10_structure"     # fmus/<name>.fmu, or a path to an .fmu
    period = 1e-3                 # s, or rate_hz = 1000
    parameters = { zeta = 0.002 }

    [[connections]]
    from = "structure.strain_diag"
    to = "ctrl_diag.y"
    gain = 1.0                    # optional: to = gain * from + offset
    offset = 0.0

    [[actions]]
    time = 2.4
    set = { "ctrl_diag.enable" = true }

    [record]
    variables = ["structure.strain_diag", "ctrl_diag.u"]

The rooms: :mod:`.model` (the dataclasses), :mod:`.toml` (the TOML layout),
:mod:`.ssp` (SSP 1.0 archives, read and written) and :func:`load_scenario`, which takes
any of them.
"""

from __future__ import annotations

from pathlib import Path

from .model import (
    Action,
    Connection,
    Experiment,
    Instance,
    Scenario,
    ScenarioError,
    check_keys,
    closest,
    parse_override,
)
from .ssp import JacobiExportWarning, read_ssp, write_ssp
from .toml import load_toml_file, read_toml, scenario_from_dict

__all__ = [
    "Action",
    "Connection",
    "Experiment",
    "Instance",
    "JacobiExportWarning",
    "Scenario",
    "ScenarioError",
    "check_keys",
    "closest",
    "load_scenario",
    "load_toml_file",
    "parse_override",
    "read_ssp",
    "read_toml",
    "scenario_from_dict",
    "write_ssp",
]


def load_scenario(scenario, base_dir=None) -> Scenario:
    """Read a scenario from a TOML file, an SSP archive, a dict or an existing Scenario.

    Parameters
    ----------
    scenario : path-like, dict or Scenario
        A ``.toml`` file, an ``.ssp`` archive, the parsed TOML layout, or a Scenario.
    base_dir : path-like, optional
        Folder for relative FMU names of a dict scenario (default: current folder).

    Returns
    -------
    Scenario
    """
    if isinstance(scenario, Scenario):
        return scenario
    if isinstance(scenario, dict):
        return scenario_from_dict(scenario, base_dir)
    path = Path(scenario)
    if path.suffix.lower() == ".ssp":
        return read_ssp(path)
    return read_toml(path, base_dir)
