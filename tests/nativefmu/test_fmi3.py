"""Native FMUs as FMI 3.0: the same kernels, validated, equal to their FMI 2.0 twins.

Each FMI 3.0 FMU is built from the same Python twin as the FMI 2.0 native FMU of the
session (``suite_fmus``), so the two carry the same model data; the FMI 2.0 twin is the
reference throughout, and the comparisons are bit for bit (same C kernels, same values
in, same order of operations), not to a tolerance.
"""

import ctypes
import shutil
import subprocess
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from nativefmu.build import CFLAGS, build_native, compile_sources, mingw_compiler

pytestmark = pytest.mark.slow

MODELS = ("truss10_structure", "piezo_p243_30", "piezo_p243_40",
          "controller_truss10_strain_diag", "controller_truss10_strain_long", "excitation",
          "acs", "disturbance", "eos_testbed_structure", "piezo_p845_37",
          "controller_eos_isolation", "controller_testbed_isolation")
REPO = Path(__file__).resolve().parents[2]
C_HOST3 = REPO / "tests" / "support" / "c_host" / "host3.c"
T = np.arange(2000) * 1e-3
EOS_EVENTS = ["dist_swir.preset=swir_cryocooler", "dist_rwa.preset=rwa",
              "dist_vnir.preset=vnir_pointing", "dist_ceres.preset=ceres_scan",
              "dist_tir.seed=4", "dist_tir.preset=tir_cryocooler",
              "ctrl_iso1.gain=0.27", "ctrl_iso2.gain=0.27", "ctrl_iso3.gain=0.27",
              "ctrl_swir.gain=0.1", "ctrl_vnir.gain=0.1"]


@pytest.fixture(scope="module")
def dirs(suite_fmi3, suite_fmu_dir):
    """{2: folder of the FMI 2.0 native FMUs, 3: folder of their FMI 3.0 builds} (the
    run's, built once for this file, test_fmi3_hostile and test_symbols)."""
    return {2: suite_fmu_dir, 3: suite_fmi3(*MODELS)}


def _md(path):
    with zipfile.ZipFile(path) as z:
        return ET.fromstring(z.read("modelDescription.xml"))


# ---------------------------------------------------------------------- model description

@pytest.mark.parametrize("model", MODELS)
def test_fmpy_fmi3_schema_validation_and_project_checks_are_clean(dirs, model):
    from fmpy.validation import validate_fmu as fmpy_validate

    from fmutools.validate import validate_fmu

    path = dirs[3] / f"{model}.fmu"
    root = _md(path)
    assert root.get("fmiVersion") == "3.0" and root.find("CoSimulation") is not None
    assert fmpy_validate(str(path)) == []          # FMI 3.0 XSD, names, ModelStructure
    assert validate_fmu(path, strict=True) == []   # units, dependencies, state flags


@pytest.mark.parametrize("model", MODELS)
def test_model_description_is_the_fmi2_twins_in_fmi3_terms(dirs, model):
    from fmpy import read_model_description

    md2 = read_model_description(str(dirs[2] / f"{model}.fmu"))
    md3 = read_model_description(str(dirs[3] / f"{model}.fmu"))
    as2 = {"Float64": "Real", "Int32": "Integer", "Boolean": "Boolean", "String": "String"}
    v2 = [(v.name, v.valueReference, v.type, v.causality, v.variability, v.unit, v.start)
          for v in md2.modelVariables]
    v3 = [(v.name, v.valueReference, as2[v.type], v.causality, v.variability, v.unit, v.start)
          for v in md3.modelVariables if v.causality != "independent"]
    assert v3 == v2
    (time,) = [v for v in md3.modelVariables if v.causality == "independent"]
    assert time.name == "time" and time.unit == "s"

    def deps(unknowns):
        return {u.variable.name: sorted(d.name for d in u.dependencies) for u in unknowns}
    assert deps(md3.outputs) == deps(md2.outputs)
    assert deps(md3.initialUnknowns) == deps(md2.initialUnknowns)
    cs2, cs3 = md2.coSimulation, md3.coSimulation
    assert cs3.modelIdentifier == cs2.modelIdentifier
    assert cs3.canHandleVariableCommunicationStepSize is True
    assert cs3.canGetAndSetFMUstate is True and cs3.canSerializeFMUstate is True
    assert md3.guid != md2.guid  # instantiation token of another binary
    assert (md3.defaultExperiment.stepSize, md3.defaultExperiment.stopTime) == (
        md2.defaultExperiment.stepSize, md2.defaultExperiment.stopTime)


# ---------------------------------------------------------------------- scenarios

def _run(scenario, out, fmu_dir, stop, overrides=()):
    from orchestrator import run_scenario

    table, meta = run_scenario(REPO / "scenarios" / scenario, out, fmu_dir=fmu_dir,
                               stop_time=stop, overrides=list(overrides))
    assert meta["status"] == "ok"
    return table


def _assert_same_table(a, b):
    assert list(a.keys()) == list(b.keys())
    for name in a.keys():
        np.testing.assert_array_equal(np.asarray(b[name]), np.asarray(a[name]), err_msg=name)


CASES = [("truss10_closed_loop.toml", 5.0, [], "structure.los_tip_pitch"),
         ("truss10_campaign.toml", 3.0, ["excitation.amp1=10.0", "ctrl_diag.gain=0.5"],
          "structure.los_tip_pitch"),
         ("eos_budget.toml", 0.3, EOS_EVENTS, "structure.los_swir_pitch")]


@pytest.mark.filterwarnings("ignore:.*not connected and keep their start values")
@pytest.mark.parametrize("scenario,stop,overrides,moving", CASES)
def test_shipped_scenarios_give_the_fmi2_table_bit_for_bit(dirs, tmp_path, monkeypatch,
                                                           scenario, stop, overrides, moving):
    """Every instance FMI 3.0 against every instance FMI 2.0, through the master's
    compiled loop (counted: it must run the FMI 3.0 instances)."""
    from orchestrator.cosim import fastloop

    ran = []
    run = fastloop.FastLoop.run
    monkeypatch.setattr(fastloop.FastLoop, "run", lambda self, *a: ran.append(1) or
                        run(self, *a))
    two = _run(scenario, tmp_path / "2", dirs[2], stop, overrides)
    ran.clear()
    three = _run(scenario, tmp_path / "3", dirs[3], stop, overrides)
    assert ran, "the compiled loop did not run the FMI 3.0 instances"
    _assert_same_table(two, three)
    assert np.max(np.abs(np.asarray(three[moving], float))) > 0  # not a table of zeros


@pytest.mark.filterwarnings("ignore:.*not connected and keep their start values")
def test_python_loop_runs_fmi3_instances_to_the_same_table(dirs, tmp_path, monkeypatch):
    from orchestrator.cosim import simulation

    two = _run("truss10_closed_loop.toml", tmp_path / "2", dirs[2], 2.0)
    monkeypatch.setattr(simulation, "fast_loop", lambda *a, **k: None)
    three = _run("truss10_closed_loop.toml", tmp_path / "3", dirs[3], 2.0)
    _assert_same_table(two, three)


@pytest.mark.filterwarnings("ignore:.*not connected and keep their start values")
@pytest.mark.parametrize("scenario,stop,overrides,three", [
    ("truss10_closed_loop.toml", 5.0, [],
     ("truss10_structure", "controller_truss10_strain_diag", "piezo_p243_30")),
    ("eos_budget.toml", 0.3, EOS_EVENTS,
     ("eos_testbed_structure", "controller_eos_isolation", "disturbance")),
])
def test_mixed_fmi2_and_fmi3_scenario_equals_the_all_fmi2_run(dirs, tmp_path, scenario, stop,
                                                              overrides, three):
    from orchestrator.cosim import read_fmu_info

    mixed = tmp_path / "mixed"
    mixed.mkdir()
    for f in dirs[2].glob("*.fmu"):
        shutil.copy2(dirs[3 if f.stem in three else 2] / f.name, mixed / f.name)
    versions = {f.stem: read_fmu_info(f).fmi_version for f in mixed.glob("*.fmu")}
    assert {versions[m] for m in three} == {"3.0"} and "2.0" in versions.values()
    _assert_same_table(_run(scenario, tmp_path / "2", dirs[2], stop, overrides),
                       _run(scenario, tmp_path / "m", mixed, stop, overrides))


# ---------------------------------------------------------------------- one FMU at a time

def run3(fmu, *, outputs, step_size, n_steps, inputs=None, state_at=None, corrupt=False):
    """Outputs after every step of an FMI 3.0 FMU in fmpy (FMU3Slave).

    With ``state_at=k`` the state is saved and serialised before step ``k``, the run goes
    on to the end, then the deserialised state is set and steps ``k..`` run again:
    returns ``(y, y_again)``.  With ``corrupt`` one byte of the serialised state is
    flipped and the deserialisation must be refused.
    """
    from fmpy import extract, read_model_description
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi3 import FMU3Slave

    md = read_model_description(str(fmu))
    var = {v.name: v.valueReference for v in md.modelVariables}
    unzip = extract(str(fmu))
    slave = FMU3Slave(guid=md.guid, unzipDirectory=unzip,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="t")
    try:
        slave.instantiate(logMessage=lambda *a: None)
        slave.enterInitializationMode(startTime=0.0)
        slave.exitInitializationMode()
        in_vrs = [var[n] for n in (inputs or {})]
        u = np.column_stack(list(inputs.values())) if inputs else None
        out_vrs = [var[n] for n in outputs]
        y = np.zeros((n_steps, len(out_vrs)))

        def steps(k0, k1, y):
            for k in range(k0, k1):
                if in_vrs:
                    slave.setFloat64(in_vrs, u[k].tolist())
                slave.doStep(currentCommunicationPoint=k * step_size,
                             communicationStepSize=step_size)
                y[k] = slave.getFloat64(out_vrs)

        if state_at is None:
            steps(0, n_steps, y)
            return y
        steps(0, state_at, y)
        state = slave.getFMUState()
        blob = slave.serializeFMUState(state)
        slave.freeFMUState(state)
        if corrupt:
            bad = bytearray(blob)
            bad[200] ^= 1
            with pytest.raises(FMICallException):
                slave.deserializeFMUState(bytes(bad))
        steps(state_at, n_steps, y)
        again = y.copy()
        state = slave.deserializeFMUState(blob)
        slave.setFMUState(state)
        slave.freeFMUState(state)
        steps(state_at, n_steps, again)
        return y, again
    finally:
        slave.terminate()
        slave.freeInstance()
        shutil.rmtree(unzip, ignore_errors=True)


STATE_CASES = [
    ("truss10_structure", ["los_tip_pitch", "strain_diag"],
     {"fc_diag": 100 * np.sin(2 * np.pi * 8.4 * T[:600])}),
    ("piezo_p243_40", ["force", "strain"], {"v_cmd": 800 * np.sin(2 * np.pi * 20 * T[:600])}),
    ("controller_truss10_strain_diag", ["u1"],
     {"y1": 1e-5 * np.sin(2 * np.pi * 8.4 * T[:600])}),
]


@pytest.mark.parametrize("model,outputs,inputs", STATE_CASES)
def test_state_round_trip_mid_run_equals_the_uninterrupted_run(dirs, model, outputs, inputs):
    from tests.support.hosts import run_fmpy

    kw = dict(outputs=outputs, step_size=1e-3, n_steps=600, inputs=inputs)
    y, again = run3(dirs[3] / f"{model}.fmu", state_at=250, corrupt=True, **kw)
    np.testing.assert_array_equal(again, y)
    np.testing.assert_array_equal(y, run_fmpy(dirs[2] / f"{model}.fmu", **kw))
    assert np.max(np.abs(y[250:])) > 0


def test_plain_c_host_runs_an_fmi3_fmu_under_an_empty_environment(dirs, tmp_path):
    """tests/support/c_host/host3.c (no libpython, no fmpy) under ``env -i`` on a copy of
    the FMU: the outputs of the FMI 2.0 twin in fmpy, bit for bit."""
    from tests.support.hosts import compile_c_host, run_c_host, run_fmpy

    host = compile_c_host(tmp_path / "host3", source=C_HOST3)
    copy = tmp_path / "copy" / "piezo_p243_40.fmu"
    copy.parent.mkdir()
    shutil.copy2(dirs[3] / copy.name, copy)
    kw = dict(outputs=["force", "voltage", "strain"], step_size=1e-3, n_steps=400,
              inputs={"v_cmd": 700 * np.sin(2 * np.pi * 25 * T[:400]),
                      "elongation": 1e-6 * np.cos(T[:400])})
    in_c = run_c_host(copy, host=host, wrapper=["env", "-i"], **kw)
    np.testing.assert_array_equal(in_c, run_fmpy(dirs[2] / copy.name, **kw))
    lib = tmp_path / "model.so"
    with zipfile.ZipFile(copy) as z:
        lib.write_bytes(z.read("binaries/x86_64-linux/piezo_p243_40.so"))
    needed = subprocess.run(["objdump", "-p", str(lib)], capture_output=True, text=True).stdout
    libs = {line.split()[1] for line in needed.splitlines() if line.strip().startswith("NEEDED")}
    assert libs <= {"libc.so.6", "libm.so.6"}, libs


def test_sources_compile_alone_and_export_every_fmi3_function(dirs, tmp_path):
    """``sources/`` alone, strict flags: a library exporting every function that
    fmi3Functions.h declares, giving the shipped binary's outputs."""
    from tests.support.hosts import compile_c_host, run_c_host

    fmu = dirs[3] / "controller_truss10_strain_diag.fmu"
    src = tmp_path / "src"
    with zipfile.ZipFile(fmu) as z:
        for name in z.namelist():
            if name.startswith("sources/"):
                (src / Path(name).name).parent.mkdir(exist_ok=True)
                (src / Path(name).name).write_bytes(z.read(name))
    assert "fmi2.c" not in {p.name for p in src.iterdir()}
    header = (src / "fmi3Functions.h").read_text()
    declared = [line.split()[-1].rstrip(";") for line in header.splitlines()
                if line.startswith("FMI3_Export")]
    lib_path = compile_sources(src, tmp_path / "rebuilt.so")
    lib = ctypes.CDLL(str(lib_path))
    assert len(declared) > 70 and all(hasattr(lib, name) for name in declared)
    lib.fmi3GetVersion.restype = ctypes.c_char_p
    assert lib.fmi3GetVersion() == b"3.0"
    assert set(CFLAGS) >= {"-Werror", "-pedantic"}
    rebuilt = tmp_path / "rebuilt.fmu"
    with zipfile.ZipFile(fmu) as zin, zipfile.ZipFile(rebuilt, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename.endswith(".so"):
                data = lib_path.read_bytes()
            zout.writestr(item, data)
    kw = dict(outputs=["u1"], step_size=1e-3, n_steps=300,
              inputs={"y1": 1e-5 * np.sin(2 * np.pi * 8.4 * T[:300])})
    host = compile_c_host(tmp_path / "host3", source=C_HOST3)
    np.testing.assert_array_equal(run_c_host(rebuilt, host=host, **kw),
                                  run_c_host(fmu, host=host, **kw))


def test_windows_dll_of_an_fmi3_fmu_exports_the_fmi3_functions(dirs, tmp_path):
    if mingw_compiler() is None:
        pytest.skip("x86_64-w64-mingw32-gcc is not installed (Debian: gcc-mingw-w64-x86-64, "
                    "`make native-deps`); the x86_64-windows binaries cannot be built here")
    from fmutools.registry import collect_specs

    (spec,) = collect_specs(["excitation"])
    fmu = build_native(spec, tmp_path, python_fmu=dirs[2] / "python" / "excitation.fmu",
                       windows=True, fmi=3)
    dll = tmp_path / "excitation.dll"
    with zipfile.ZipFile(fmu) as z:
        dll.write_bytes(z.read("binaries/x86_64-windows/excitation.dll"))
    dump = subprocess.run(["x86_64-w64-mingw32-objdump", "-p", str(dll)], capture_output=True,
                          text=True).stdout
    assert dll.read_bytes()[:2] == b"MZ"
    for name in ("fmi3InstantiateCoSimulation", "fmi3DoStep", "fmi3GetFMUState",
                 "fmi3SerializeFMUState", "fmi3GetFloat64"):
        assert name in dump, name


# ---------------------------------------------------------------------- command line

def test_jitterfmu_build_fmi3_writes_fmi3_fmus(tmp_path, capsys):
    from orchestrator.cli import main

    assert main(["build", "--fmi", "3", "--model", "excitation", "--out", str(tmp_path)]) == 0
    root = _md(tmp_path / "excitation.fmu")
    assert root.get("fmiVersion") == "3.0"
    with zipfile.ZipFile(tmp_path / "excitation.fmu") as z:
        names = set(z.namelist())
    assert {"binaries/x86_64-linux/excitation.so", "sources/fmi3.c", "sources/jfcore.c",
            "sources/buildDescription.xml"} <= names
    assert not (tmp_path / "python").exists()   # the Python twins are FMI 2.0 only
    assert main(["build", "--fmi", "3", "--python", "--out", str(tmp_path)]) == 2  # usage
    assert "FMI 2.0 only" in capsys.readouterr().err
