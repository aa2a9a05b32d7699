"""The EOS experiments' shared inputs: the budget scenario and campaign, and their FMUs.

The budget (Fig. 8), the testbed isolation (Figs. 13-16) and the SWIR isolation
(Fig. 9) all run the EOS Dynamics Testbed structure of ``scenarios/eos_budget.toml``;
the budget and SWIR isolation also need the structure with every SWIR/VNIR mount leg
active (``eos_testbed_mounts_structure``), which the FMU registry does not list.
"""

from __future__ import annotations

from pathlib import Path

from fmutools.ensure import ensure_fmus as _ensure
from structfmu.fmuspec import spec_from_model
from structfmu.models import eos_testbed

from . import CAMPAIGNS, SCENARIOS

__all__ = ["SCENARIO", "CAMPAIGN", "STRUCTURE", "MOUNTS_STRUCTURE", "FMUS",
           "mounts_structure_model", "ensure_fmus"]

SCENARIO = SCENARIOS / "eos_budget.toml"
CAMPAIGN = CAMPAIGNS / "eos_budget.toml"
STRUCTURE = "eos_testbed_structure"
MOUNTS_STRUCTURE = "eos_testbed_mounts_structure"
#: What the budget campaign runs (the all-legs structure is built besides).
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
