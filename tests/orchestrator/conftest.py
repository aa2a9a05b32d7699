"""Test FMUs for the master, built once per session with fmukit; a fresh private cache."""

import sys
import zipfile
from pathlib import Path

import pytest

from fmutools import fmucache

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE / "fmus"))

SLAVES = {
    "MtIntegrator": "mastertest_slaves:Integrator",
    "MtGain": "mastertest_slaves:Gain",
    "MtFaulty": "mastertest_slaves:Faulty",
}


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory):
    """Folder with MtIntegrator.fmu, MtGain.fmu, MtFaulty.fmu and MtGainNoState.fmu."""
    from fmutools.build import FmuSpec, build_fmu

    out = tmp_path_factory.mktemp("master_fmus")
    for ident, cls in SLAVES.items():
        build_fmu(FmuSpec(model_identifier=ident, slave_class=cls), out)
        # the build imports the slave package from its temporary stage folder; forget
        # it so the next build bundles the source tree again
        sys.modules.pop("mastertest_slaves", None)
    # a copy whose model description denies fmi2Get/SetFMUstate (never instantiated)
    src, dst = out / "MtGain.fmu", out / "MtGainNoState.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'canGetAndSetFMUstate="true"',
                                    b'canGetAndSetFMUstate="false"')
            zout.writestr(item, data)
    return out


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A fresh cache folder and a fresh per-process memo of checked entries."""
    root = tmp_path / "cache"
    monkeypatch.setenv("JITTERFMU_CACHE", str(root))
    monkeypatch.setattr(fmucache, "_VERIFIED", set())
    return root


@pytest.fixture(scope="module")
def eos_loops(suite_fmu_dir):
    """The EOS budget's nominal loops (RWA case), isolation off and on, and the runner."""
    from orchestrator.campaign import LinearRunner, load_campaign
    from orchestrator.experiments import eos

    fmu_dir = eos.ensure_fmus(suite_fmu_dir)
    camp = load_campaign(eos.CAMPAIGN)
    runner = LinearRunner(camp.scenario_dir, fmu_dir=fmu_dir)
    cases = {c.configuration: c for c in camp.cases if c.event == "RWA"}
    return {cf: runner.compiled(c.scenario) for cf, c in cases.items()}, runner, cases
