"""The container FMU as FMI 3.0 (``jitterfmu export-fmu --fmi 3``) against the master.

The FMI 3.0 container runs the same FMI 2.0 units through the same ``container.c`` as
the FMI 2.0 container (``test_container.py``); only the outer API differs.  Reference:
``run_scenario`` of the same scenario with the same native FMUs, compared with
``assert_array_equal`` (same kernels, same calls, same order: the same bits).
"""

from __future__ import annotations

import re
import subprocess
import warnings
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.validation import validate_fmu

from nativefmu.build import _fmi_header_dir, mingw_compiler
from nativefmu.container import ContainerError, export_fmu
from orchestrator import load_scenario, run_scenario

REPO = Path(__file__).resolve().parents[2]
C_HOST3 = REPO / "tests" / "support" / "c_host" / "host3.c"
TRUSS = ["truss10_structure", "piezo_p243_40", "piezo_p243_30", "controller_truss10_strain_diag",
         "controller_truss10_strain_long", "excitation"]
STOP = 12.0
# test_container.MIXED without the connection to ctrl_diag.r1 (a free input then) and
# without the action: the dependency of ctrl_diag.u1 on r1 within a step shows
SMALL = """
[experiment]
stop = 1.2
output_interval = 1e-3
[fmus.structure]
fmu = "truss10_structure"
period = 1e-3
[fmus.piezo_diag]
fmu = "piezo_p243_40"
period = 1e-3
[fmus.ctrl_diag]
fmu = "controller_truss10_strain_diag"
period = 4e-3
parameters = { t_on = 0.3 }
[[connections]]
from = "structure.strain_diag"
to = "ctrl_diag.y1"
[[connections]]
from = "ctrl_diag.u1"
to = "piezo_diag.v_cmd"
[[connections]]
from = "piezo_diag.force"
to = "structure.fc_diag"
[[connections]]
from = "structure.elong_diag"
to = "piezo_diag.elongation"
[record]
variables = ["structure.strain_diag", "ctrl_diag.u1", "piezo_diag.voltage",
             "piezo_diag.force", "structure.los_tip_pitch"]
"""


def _quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kw)


@pytest.fixture(scope="module")
def truss(suite_container, suite_fmu_dir):
    """(scenario, master table over 12 s, FMI 3.0 container written by the CLI: the
    run's)."""
    path = REPO / "scenarios" / "truss10_closed_loop.toml"
    out = suite_container(path, 3)
    sc = load_scenario(path)
    table, meta = _quiet(run_scenario, sc, stop_time=STOP, fmu_dir=suite_fmu_dir)
    assert meta["status"] == "ok"
    return sc, table, out


@pytest.fixture(scope="module")
def small(suite_fmus, suite_fmu_dir, tmp_path_factory):
    """The small scenario as an FMI 3.0 container with ctrl_diag.gain exposed (its
    Linux binary; the Windows one is checked on the truss's)."""
    suite_fmus(*TRUSS)
    tmp = tmp_path_factory.mktemp("container3_small")
    (tmp / "small.toml").write_text(SMALL)
    return _quiet(export_fmu, tmp / "small.toml", tmp / "small3.fmu", fmi=3,
                  parameters=["ctrl_diag.gain"], fmu_dir=suite_fmu_dir, windows=False)


def _assert_master_table(table, times, columns, names, base=1e-3):
    """Every signal at the instants both report (the master records every 4 ms here)
    equals the master's, bit for bit."""
    tm = np.rint(np.asarray(table["time"]) / base).astype(np.int64)
    tc = np.rint(np.asarray(times) / base).astype(np.int64)
    _, im, ic = np.intersect1d(tm, tc, return_indices=True)
    assert len(im) >= min(len(tm), len(tc)) - 1, "the instants hardly overlap"
    moving = 0
    for name, col in zip(names, columns):
        ref = np.asarray(table[name], float)[im]
        np.testing.assert_array_equal(np.asarray(col, float)[ic], ref, err_msg=name)
        moving += bool(np.any(ref != 0))
    assert moving >= len(names) // 2, "most signals are zero: nothing compared"


def test_fmpy_fmi3_validation_passes_and_the_description_is_fmi3(truss):
    """fmpy's FMI 3.0 schema and rule validation finds nothing; time is the independent
    variable on the value reference after the container's, outputs keep their units."""
    _, _, fmu = truss
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu))
    assert md.fmiVersion == "3.0"
    by = {v.name: v for v in md.modelVariables}
    time = by["time"]
    assert time.causality == "independent"
    assert time.valueReference == 1 + max(v.valueReference for v in md.modelVariables
                                          if v.name != "time")
    assert by["structure.los_tip_pitch"].unit == "rad"
    assert by["structure.los_tip_pitch"].type == "Float64"
    with zipfile.ZipFile(fmu) as z:
        names = set(z.namelist())
    assert {f"binaries/x86_64-linux/{fmu.stem}.so", "sources/container_fmi3.c",
            "sources/container.c", "sources/buildDescription.xml"} <= names
    assert not any(n.startswith("binaries/linux64/") for n in names)


def test_dependencies_are_value_references_of_the_fmi2_structure(small):
    """Output and InitialUnknown dependencies name value references: ctrl_diag.u1 on the
    free input ctrl_diag.r1 within a step, and on the exposed gain at initialisation."""
    md = read_model_description(str(small))
    assert validate_fmu(str(small)) == []
    step = {u.variable.name: {d.name for d in u.dependencies} for u in md.outputs}
    init = {u.variable.name: {d.name for d in u.dependencies} for u in md.initialUnknowns}
    assert step["ctrl_diag.u1"] == {"ctrl_diag.r1"}
    assert step["piezo_diag.force"] == set() == step["structure.strain_diag"]
    assert {"ctrl_diag.gain", "ctrl_diag.r1"} <= init["ctrl_diag.u1"]
    runs = [fmpy.simulate_fmu(str(small), stop_time=0.6, output_interval=1e-3,
                              start_values={"ctrl_diag.gain": g, "ctrl_diag.r1": 20.0},
                              output=["ctrl_diag.u1"]) for g in (1.0, 0.5)]
    assert np.max(np.abs(runs[0]["ctrl_diag.u1"] - runs[1]["ctrl_diag.u1"])) > 0


@pytest.mark.parametrize("mult", [1, 4])
def test_fmpy_steps_the_fmi3_container_as_the_master_runs(truss, mult):
    """fmpy.simulate_fmu (FMI 3.0) at the base step and at 4x it: the master's table,
    every recorded signal bit for bit over 12 s."""
    sc, table, fmu = truss
    res = fmpy.simulate_fmu(str(fmu), stop_time=STOP, output_interval=mult * 1e-3,
                            output=list(sc.record))
    assert len(res) == int(round(STOP / (mult * 1e-3))) + 1
    _assert_master_table(table, res["time"], [res[r] for r in sc.record], list(sc.record))


def test_a_step_of_one_and_a_half_base_ticks_is_an_fmi3_error(truss, capfd):
    """An error naming fmi3DoStep and the allowed steps, not a wrong answer."""
    _, _, fmu = truss
    with pytest.raises(Exception, match="fmi3DoStep failed with status 3"):
        fmpy.simulate_fmu(str(fmu), stop_time=0.03, output_interval=1.5e-3)
    out = capfd.readouterr()
    assert ("fmi3DoStep: communication step 0.0015 s is not a whole number of base steps; "
            "allowed steps are m x 0.001 s") in out.out + out.err


def test_state_round_trip_mid_run_replays_and_time_is_the_tick(small, tmp_path):
    """getFMUState / serialise at step 250, run on, deserialise and set it back, run
    again: the same outputs bit for bit (the free reference ctrl_diag.r1 at 20 moves the
    loop from t_on = 0.3 s); a flipped byte is refused.  ``time`` reads the
    tick's exact time k / 1000 s."""
    from fmpy.fmi3 import FMU3Slave

    md = read_model_description(str(small))
    vrs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    by = {v.name: v.valueReference for v in md.modelVariables}
    t_vr = by["time"]
    s = FMU3Slave(guid=md.guid, unzipDirectory=extract(str(small), str(tmp_path / "x")),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="c")
    s.instantiate()
    s.setFloat64([by["ctrl_diag.r1"]], [20.0])   # a reference step into the loop at t_on
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    h = 1e-3
    for k in range(250):
        s.doStep(k * h, h)
    assert s.getFloat64([t_vr]) == [250 / 1000]
    saved = bytes(s.serializeFMUState(s.getFMUState()))

    def run_on(k0):
        rows = []
        for k in range(k0, k0 + 500):
            s.doStep(k * h, h)
            rows.append(s.getFloat64(vrs))
        return np.array(rows)
    first = run_on(250)
    assert s.getFloat64([t_vr]) == [750 / 1000]
    assert np.max(np.abs(first)) > 0
    bad = bytearray(saved)
    bad[len(bad) // 2] ^= 0x10
    with pytest.raises(Exception):
        s.setFMUState(s.deserializeFMUState(bytes(bad)))
    s.setFMUState(s.deserializeFMUState(saved))
    assert s.getFloat64([t_vr]) == [250 / 1000]
    np.testing.assert_array_equal(run_on(250), first)
    s.terminate()
    s.freeInstance()


def test_plain_c_host3_runs_the_fmi3_container_under_an_empty_environment(truss, tmp_path):
    """tests/support/c_host/host3.c (no Python in the process) under ``env -i``, 4 ms
    steps (the recording interval) over the 12 s: the master's table bit for bit; host3 also checks lastSuccessfulTime = t + h
    and that no step terminates or returns early."""
    from tests.support.hosts import compile_c_host, run_c_host

    sc, table, fmu = truss
    names = list(sc.record)
    n = 3000
    y = run_c_host(fmu, outputs=names, step_size=4e-3, n_steps=n,
                   host=compile_c_host(tmp_path / "host3", source=C_HOST3),
                   wrapper=["env", "-i"])
    _assert_master_table(table, 4e-3 * np.arange(1, n + 1), y.T, names)


def test_an_unknown_fmi_version_and_an_fmi3_inner_fmu_are_refused(truss, tmp_path,
                                                                  suite_fmu_dir):
    """fmi=4 is one sentence; a scenario whose FMUs are the FMI 3.0 native build names
    them (a container holds the FMI 2.0 build of each)."""
    from nativefmu.build import build_all_native

    sc, _, _ = truss
    with pytest.raises(ContainerError, match=r"^fmi=4 is not an FMI version .*use 2 or 3$"):
        export_fmu(sc, tmp_path / "x.fmu", fmi=4, fmu_dir=suite_fmu_dir)
    fmi3_dir = tmp_path / "fmi3"
    fmus, _, problems = _quiet(build_all_native, fmi3_dir, ["excitation"], fmi=3)
    assert not problems and fmus
    for name in TRUSS[:-1]:
        (fmi3_dir / f"{name}.fmu").symlink_to(suite_fmu_dir / f"{name}.fmu")
    with pytest.raises(ContainerError, match=r"excitation \(excitation\.fmu: an FMI 3\.0 "
                       r"native FMU; a container holds the FMI 2\.0 build"):
        _quiet(export_fmu, sc, tmp_path / "x.fmu", fmi=3, fmu_dir=fmi3_dir)


def _fmi3_functions() -> set:
    text = (_fmi_header_dir() / "fmi3Functions.h").read_text()
    return set(re.findall(r"^FMI3_Export fmi3(\w+)TYPE", text, re.M))


def test_linux_binary_exports_every_fmi3_function_and_no_fmi2_one(truss, tmp_path):
    """Every function of fmi3Functions.h and nothing else (its FMI 2.0 API, ct2_fmi2...,
    and the inner units' uN_fmi2... stay inside), libc and libm only."""
    _, _, fmu = truss
    lib = tmp_path / "t.so"
    with zipfile.ZipFile(fmu) as z:
        lib.write_bytes(z.read(f"binaries/x86_64-linux/{fmu.stem}.so"))
    out = subprocess.run(["nm", "-D", "--defined-only", str(lib)], capture_output=True,
                         text=True, check=True).stdout
    names = {ln.split()[-1] for ln in out.splitlines() if len(ln.split()) == 3}
    assert {f"fmi3{f}" for f in _fmi3_functions()} <= names
    assert {n for n in names if not n.startswith("fmi3")} == set()
    dump = subprocess.run(["objdump", "-p", str(lib)], capture_output=True, text=True).stdout
    libs = {line.split()[1] for line in dump.splitlines() if line.strip().startswith("NEEDED")}
    assert libs <= {"libc.so.6", "libm.so.6"}, libs
    assert str(REPO).encode() not in lib.read_bytes()


@pytest.mark.skipif(mingw_compiler() is None, reason="x86_64-w64-mingw32-gcc is not "
                    "installed (make native-deps); the x86_64-windows binary is not built")
def test_windows_dll_of_the_fmi3_container_exports_the_fmi3_functions(truss, tmp_path):
    _, _, fmu = truss
    dll = tmp_path / "c.dll"
    with zipfile.ZipFile(fmu) as z:
        dll.write_bytes(z.read(f"binaries/x86_64-windows/{fmu.stem}.dll"))
    assert dll.read_bytes()[:2] == b"MZ"
    dump = subprocess.run(["x86_64-w64-mingw32-objdump", "-p", str(dll)], capture_output=True,
                          text=True).stdout
    exported = set(re.findall(r"\]\s+(\w+)$", dump, re.M)) | set(re.findall(r"\s(fmi\w+)$",
                                                                          dump, re.M))
    assert {f"fmi3{f}" for f in _fmi3_functions()} <= exported
    assert not {n for n in exported if n.startswith("fmi2")}


def test_a_resource_path_with_a_space_and_a_percent_sign_reaches_the_inner_units(small,
                                                                                 tmp_path):
    """resourcePath is a native path; the inner FMI 2.0 units get it as a percent-encoded
    file URI and read their resources (the structure's matrices) from it: the same
    outputs as from a plain path, where a path passed on unencoded would be decoded to
    another folder ("%41" is "A") and the structure could not load."""
    from fmpy.fmi3 import FMU3Slave

    md = read_model_description(str(small))
    vrs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    r1 = next(v.valueReference for v in md.modelVariables if v.name == "ctrl_diag.r1")

    def run(folder):
        s = FMU3Slave(guid=md.guid, unzipDirectory=extract(str(small), str(folder)),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="c")
        s.instantiate()
        s.setFloat64([r1], [20.0])
        s.enterInitializationMode(startTime=0.0)
        s.exitInitializationMode()
        rows = []
        for k in range(400):
            s.doStep(k * 1e-3, 1e-3)
            rows.append(s.getFloat64(vrs))
        s.terminate()
        s.freeInstance()
        return np.array(rows)

    plain = run(tmp_path / "plain")
    assert np.max(np.abs(plain)) > 0
    np.testing.assert_array_equal(run(tmp_path / "a b%41c"), plain)
