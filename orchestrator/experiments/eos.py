"""The EOS experiments' shared inputs: the budget scenario and campaign, and their FMUs.

The budget (Fig. 8), the testbed isolation (Figs. 13-16) and the SWIR isolation
(Fig. 9) all run the EOS Dynamics Testbed structure of ``scenarios/eos_budget.toml``;
the budget and SWIR isolation also need the structure with every SWIR/VNIR mount leg
active (``eos_testbed_mounts_structure``), which the FMU registry does not list.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from acsfmu.design import pid_gains_for
from acsfmu.filters import AcsFilters
from acsfmu.pid import AcsConfig, PidGains
from distfmu.presets import get_preset
from fmutools.ensure import ensure_fmus as _ensure
from structfmu.fmuspec import spec_from_model
from structfmu.models import eos_testbed

from . import CAMPAIGNS, SCENARIOS

__all__ = ["SCENARIO", "CAMPAIGN", "STRUCTURE", "MOUNTS_STRUCTURE", "FMUS", "ACS_INERTIA",
           "ACS_PARAMETERS", "mounts_structure_model", "ensure_fmus", "acs_config", "wrench",
           "leg_loops"]

SCENARIO = SCENARIOS / "eos_budget.toml"
CAMPAIGN = CAMPAIGNS / "eos_budget.toml"
STRUCTURE = "eos_testbed_structure"
MOUNTS_STRUCTURE = "eos_testbed_mounts_structure"
#: What the budget campaign runs (the all-legs structure is built besides).
ACS_INERTIA = (378.0, 827.0, 1123.0)   # as scenarios/eos_budget.toml (kg m^2)
#: The ACS design of scenarios/eos_budget.toml (tested equal to the scenario's), designed
#: on the flexible plant (docs/robustness.md): PID design phase 60 deg, crossovers
#: 0.05 / 0.05 / 0.04 Hz (roll, pitch, yaw), the 0.5 Hz array mode phase-stabilised
#: (damped through roll), a notch at the 1.407 Hz roll mode, 0.3 Hz low-passes on pitch
#: and yaw (Hz, rad, dimensionless).
ACS_PARAMETERS = {"phase_margin": 1.0471975511965976, "bandwidth": 0.04,
                  "bandwidth_x": 0.05, "bandwidth_y": 0.05, "notch_hz_x": 1.407,
                  "notch_zeta_num_x": 0.1, "notch_zeta_den_x": 0.3, "lowpass_hz_y": 0.3,
                  "lowpass_hz_z": 0.3}
FMUS = ("eos_testbed_structure", "disturbance", "acs", "piezo_p845_37",
        "controller_testbed_isolation", "controller_eos_isolation")


def mounts_structure_model():
    """Reduced EOS testbed with every SWIR/VNIR mount leg active (``ReducedModel``)."""
    return eos_testbed.reduced(truss=eos_testbed.build(active_legs="all"))


def ensure_fmus(fmu_dir="fmus", names=FMUS, kind="native") -> Path:
    """Build the named FMUs and the all-legs structure into ``fmu_dir`` when missing or
    stale; returns the folder, resolved.

    Parameters
    ----------
    fmu_dir : path-like
        Folder of built FMUs.
    names : iterable of str
        Registry FMUs to build besides ``MOUNTS_STRUCTURE``.
    kind : {"native", "python"}
        Which build (the Python twins are built for either).
    """
    fmu_dir = Path(fmu_dir)
    _ensure(list(names) + [MOUNTS_STRUCTURE], fmu_dir, extra={
        MOUNTS_STRUCTURE: lambda: spec_from_model(
            mounts_structure_model(), MOUNTS_STRUCTURE,
            "EOS testbed, every SWIR/VNIR mount leg active")}, kind=kind)
    return fmu_dir.resolve()


def acs_config():
    """The ACS of the scenario at 10 Hz: inertias ``ACS_INERTIA`` and the design
    ``ACS_PARAMETERS``, as the ACS FMU builds its configuration from them."""
    T = 0.1
    p = ACS_PARAMETERS
    phase = math.degrees(p.get("phase_margin", math.radians(50.0)))
    g = [pid_gains_for(j, p.get(f"bandwidth_{a}") or p["bandwidth"], phase, T)
         for j, a in zip(ACS_INERTIA, "xyz")]
    kp, ki, kd = (list(x) for x in zip(*g))
    filters = AcsFilters(sample_time=T,
                         notch_hz=[p.get(f"notch_hz_{a}", 0.0) for a in "xyz"],
                         notch_zeta_num=[p.get(f"notch_zeta_num_{a}", 0.05) for a in "xyz"],
                         notch_zeta_den=[p.get(f"notch_zeta_den_{a}", 0.5) for a in "xyz"],
                         lowpass_hz=[p.get(f"lowpass_hz_{a}", 0.0) for a in "xyz"])
    return AcsConfig(PidGains(kp, ki, kd), sample_time=T, filters=filters)


def wrench(t, preset: str, scale: float = 1.0):
    """A disturbance preset's wrench at the times ``t`` (s), times ``scale``.

    Parameters
    ----------
    t : array_like, shape (n,)
        Times (s).
    preset : str
        Disturbance preset name (:data:`distfmu.presets.PRESETS`).
    scale : float
        Load factor, e.g. 0.1 for the 1/10-scale testbed (-).

    Returns
    -------
    ndarray, shape (n, 6)
        Forces (N) then moments (N m).
    """
    w = np.asarray(get_preset(preset).source.wrench(np.asarray(t)), float)
    return scale * (w.T if w.shape[0] == 6 and w.shape[-1] != 6 else w)


def leg_loops(legs, period: float, central_fmu=None):
    """The mount legs' loops of the all-legs scenarios: instances and connections.

    Per leg a ``piezo_p845_37`` stack in series with it (its force into
    ``structure.fc_<leg>``, the leg's elongation back) and a ``controller_eos_isolation``
    law on the leg's strain (``ctrl_<leg>``, gain 0), or one law ``ctrl_central`` of the
    FMU ``central_fmu`` for all legs (inputs and outputs in ``legs`` order).

    Parameters
    ----------
    legs : sequence of str
        Leg names (``structfmu.models.eos_testbed``), e.g. ``swir_mount1``.
    period : float
        Stack and law period (s).
    central_fmu : str, optional
        The FMU of one law for all legs.

    Returns
    -------
    (fmus, connections) : dict and list of dict
        As a scenario TOML file gives them.
    """
    fmus, conns = {}, []
    if central_fmu is not None:
        fmus["ctrl_central"] = {"fmu": central_fmu, "period": period,
                                "parameters": {"gain": 0.0}}
    for i, leg in enumerate(legs, 1):
        fmus[f"piezo_{leg}"] = {"fmu": "piezo_p845_37", "period": period}
        if central_fmu is not None:
            conns += [{"from": f"structure.strain_{leg}", "to": f"ctrl_central.y{i}"},
                      {"from": f"ctrl_central.u{i}", "to": f"piezo_{leg}.v_cmd"}]
        else:
            fmus[f"ctrl_{leg}"] = {"fmu": "controller_eos_isolation", "period": period,
                                   "parameters": {"gain": 0.0}}
            conns += [{"from": f"structure.strain_{leg}", "to": f"ctrl_{leg}.y1"},
                      {"from": f"ctrl_{leg}.u1", "to": f"piezo_{leg}.v_cmd"}]
        conns += [{"from": f"piezo_{leg}.force", "to": f"structure.fc_{leg}"},
                  {"from": f"structure.elong_{leg}", "to": f"piezo_{leg}.elongation"}]
    return fmus, conns
