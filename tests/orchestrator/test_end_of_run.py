"""FMI end of run: an FMU that asks to terminate ends the run normally; validate
separates FMI 2.0 errors from this project's conventions."""

import json
import subprocess
import warnings
import zipfile
from pathlib import Path

import pytest
import tomli_w

from orchestrator.cli import main
from orchestrator import EarlyEndWarning, SimulationError, run_scenario
from orchestrator.results import read_table

HERE = Path(__file__).parent

# The variables of the FMI 2.0 Reference FMU "Stair" (time without a unit, an output
# without a dependencies attribute), plus two parameters to steer the test.
STAIR_MD = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Stair"
  guid="{8c4e810f-3df3-4a00-8276-176fa3c9f008}" variableNamingConvention="structured"
  numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="Stair" canHandleVariableCommunicationStepSize="true"
    canGetAndSetFMUstate="true"/>
  <DefaultExperiment startTime="0" stopTime="10" stepSize="0.2"/>
  <ModelVariables>
    <ScalarVariable name="time" valueReference="0" causality="independent"
      variability="continuous" description="Simulation time"><Real/></ScalarVariable>
    <ScalarVariable name="counter" valueReference="1" causality="output"
      variability="discrete" initial="exact"><Integer start="1"/></ScalarVariable>
    <ScalarVariable name="limit" valueReference="2" causality="parameter"
      variability="fixed"><Integer start="10"/></ScalarVariable>
    <ScalarVariable name="terminate" valueReference="3" causality="parameter"
      variability="fixed"><Boolean start="true"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Outputs><Unknown index="2"/></Outputs>
  </ModelStructure>
</fmiModelDescription>
"""


@pytest.fixture(scope="module")
def stair(tmp_path_factory):
    """Stair.fmu built from tests/orchestrator/fmus/stair/stair.c."""
    out = tmp_path_factory.mktemp("stair")
    so = out / "Stair.so"
    subprocess.run(["cc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O1",
                    "-shared", "-fPIC", "-o", str(so), str(HERE / "fmus/stair/stair.c"), "-lm"],
                   check=True)
    fmu = out / "Stair.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.writestr("modelDescription.xml", STAIR_MD)
        z.write(so, "binaries/linux64/Stair.so")
    return fmu


def scenario(fmu, stop=12.0, **params):
    return {
        "experiment": {"stop": stop, "output_interval": 0.2},
        "fmus": {"stair": {"fmu": str(fmu), "period": 0.2, "parameters": params}},
        "record": {"variables": ["stair.counter"]},
    }


def test_fmu_that_asks_to_terminate_ends_the_run_normally(stair, tmp_path):
    with pytest.warns(EarlyEndWarning, match=r"instance 'stair' ended the run at t = 8.8 s "
                      r"\(fmi2Terminated\): counter reached 10: end of simulation; 46 rows"):
        result = run_scenario(scenario(stair), tmp_path / "o")
    table, meta = result
    assert meta["status"] == "terminated" and meta["error"] is None
    assert meta["terminated"]["instance"] == "stair" and meta["terminated"]["time"] == 8.8
    assert meta["terminated"]["last_successful_time"] == pytest.approx(9.0)
    # rows at 0, 0.2, ..., 8.8, and the row FMPy and fmusim record at
    # fmi2LastSuccessfulTime: 9.0, where the FMU's counter reached 10 and it stopped
    assert meta["rows"] == 46 and table["time"][-1] == pytest.approx(9.0)
    assert table["time"][-2] == pytest.approx(8.8)
    assert list(table["stair.counter"][::5]) == list(range(1, 11))
    assert json.loads((tmp_path / "o/run.json").read_text())["status"] == "terminated"
    assert len(read_table(tmp_path / "o/results.parquet")["time"]) == 46


def test_terminated_run_exits_0_from_the_cli(stair, tmp_path, capsys):
    scen = tmp_path / "stair.toml"
    scen.write_text(tomli_w.dumps(scenario(stair)))
    code = main(["run", str(scen), "--out", str(tmp_path / "o"), "--quiet"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "ended the run at t = 8.8 s (fmi2Terminated)" in err
    assert "46 rows" in out


def test_discard_without_terminate_is_still_a_failure(stair, tmp_path):
    with pytest.raises(SimulationError, match=r"instance 'stair' failed in fmi2DoStep at "
                       r"t = 8.8 s with status Discard: counter would reach 10"):
        run_scenario(scenario(stair, terminate=False), tmp_path / "o")
    assert json.loads((tmp_path / "o/run.json").read_text())["status"] == "error"


def test_run_that_reaches_stop_time_is_ok(stair, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error", EarlyEndWarning)
        result = run_scenario(scenario(stair, stop=5.0))
    assert result.metadata["status"] == "ok" and "terminated" not in result.metadata
    assert result.metadata["rows"] == 26


# ------------------------------------------------------------------------ validate
def test_validate_accepts_a_valid_fmi2_fmu_with_warnings_for_conventions(stair, capsys):
    assert main(["validate", str(stair)]) == 0
    out = capsys.readouterr().out
    assert "warning: Stair.fmu: Real variable 'time' has no unit" in out
    assert "warning: Stair.fmu: output 'counter' has no dependencies attribute" in out
    assert "error:" not in out
    assert out.splitlines()[-1] == "1 FMU valid (1 with warnings)"
    assert main(["validate", str(stair), str(stair)]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "2 FMUs valid (2 with warnings)"


def test_validate_strict_makes_conventions_errors(stair, capsys):
    assert main(["validate", "--strict", str(stair)]) == 1
    assert "error: Stair.fmu: Real variable 'time' has no unit" in capsys.readouterr().out


def test_validate_still_fails_fmi_errors(stair, tmp_path, capsys):
    broken = tmp_path / "Broken.fmu"
    with zipfile.ZipFile(stair) as zin, zipfile.ZipFile(broken, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":  # two variables share a name
                data = data.replace(b'name="limit"', b'name="counter"')
            zout.writestr(item, data)
    assert main(["validate", str(broken)]) == 1
    out = capsys.readouterr().out
    assert out.startswith("error: Broken.fmu: ") and "counter" in out
    not_zip = tmp_path / "x.fmu"
    not_zip.write_bytes(b"x")
    assert main(["validate", str(not_zip)]) == 1
    assert "is not a zip archive" in capsys.readouterr().out
    assert main(["validate", str(stair), str(not_zip)]) == 1
    assert capsys.readouterr().out.splitlines()[-1] == "1 of 2 FMUs invalid"


def test_library_validation_is_strict_by_default_as_for_the_build(stair):
    """fmutools.registry builds the project's FMUs and calls validate_fmu(path, strict=True)."""
    from fmutools.validate import check_fmu, validate_fmu

    errors, conventions = check_fmu(stair)
    assert errors == () and len(conventions) == 2
    assert validate_fmu(stair) == list(conventions)
    assert validate_fmu(stair, strict=False) == []


# ------------------------------------------------------------ failed initialisation
@pytest.fixture(scope="module")
def init_fails(tmp_path_factory, fmu_dir):
    """InitFails.fmu next to the master's test FMUs (a copy of that folder)."""
    import shutil
    import sys

    from fmutools.build import FmuSpec, build_fmu

    out = tmp_path_factory.mktemp("init_fails")
    for f in fmu_dir.glob("*.fmu"):
        shutil.copy(f, out)
    sys.path.insert(0, str(HERE / "fmus"))
    try:
        build_fmu(FmuSpec("MtInitFails", "hardtest_slaves:InitFails"), out)
    finally:
        sys.modules.pop("hardtest_slaves", None)
    return out


def test_fmu_that_fails_to_initialise_gives_its_reason_and_no_crash(init_fails, tmp_path):
    """Issue 12: exit 139 after the error line, and no reason given.  The failing FMU
    comes first so that it is not the last one instantiated (whose logger fmpy's
    proxy used to receive every instance's messages)."""
    scen = tmp_path / "s.toml"
    scen.write_text(tomli_w.dumps({
        "experiment": {"stop": 0.01, "output_interval": 1e-3},
        "fmus": {"f": {"fmu": "MtInitFails", "period": 1e-3, "parameters": {"bad": True}},
                 "i": {"fmu": "MtIntegrator", "period": 1e-3},
                 "g": {"fmu": "MtGain", "period": 1e-3}},
        "connections": [{"from": "i.x", "to": "f.u"}, {"from": "f.y", "to": "g.u"}],
        "record": {"variables": ["i.x"]},
    }))
    import sys

    proc = subprocess.run(
        [sys.executable, "-c", "import sys; from orchestrator.cli import main; "
         "sys.exit(main(sys.argv[1:]))", "run", str(scen), "--out", str(tmp_path / "o"),
         "--fmu-dir", str(init_fails), "--quiet"],
        capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, (proc.returncode, proc.stderr)
    assert ("instance 'f' failed in initialisation at t = 0.0 s with status Fatal: "
            in proc.stderr)
    assert "ValueError('parameter bad is true: refusing to initialise')" in proc.stderr
    assert json.loads((tmp_path / "o/run.json").read_text())["status"] == "error"


@pytest.mark.parametrize("kind, reason", [
    ("python", "internal_step must be a positive finite number, got 0.0"),
    ("native", "internal_step and i_max must be positive"),
])
def test_ten_bay_run_with_a_piezo_that_cannot_initialise_exits_cleanly(tmp_path, suite_fmus,
                                                                       suite_fmu_dir, kind,
                                                                       reason):
    """Issue 12: ``--set piezo_diag.internal_step=0`` on the ten-bay scenario printed
    the error line, then died with a segfault (exit 139) without saying why."""
    import sys
    import tomllib

    root = HERE.parents[1]
    scen = root / "scenarios/truss10_closed_loop.toml"
    names = [spec["fmu"] for spec in tomllib.loads(scen.read_text())["fmus"].values()]
    suite_fmus(*names)
    flags = ["--python-fmus"] if kind == "python" else []
    proc = subprocess.run(
        [sys.executable, "-c", "import sys; from orchestrator.cli import main; "
         "sys.exit(main(sys.argv[1:]))", "run", str(scen), "--set", "piezo_diag.internal_step=0",
         "--out", str(tmp_path / "o"), "--fmu-dir", str(suite_fmu_dir), "--quiet",
         "--stop-time", "0.1", *flags],
        capture_output=True, text=True, timeout=600, cwd=root)
    assert proc.returncode == 1, (proc.returncode, proc.stderr)
    assert "instance 'piezo_diag' failed in initialisation" in proc.stderr
    assert reason in proc.stderr
