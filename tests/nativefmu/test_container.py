"""The container FMU (``jitterfmu export-fmu``) against the master it packs.

Reference: ``run_scenario`` of the same scenario with the same native FMUs.  The
container runs the same C kernels through the same calls in the same order, so the
expectation is bit-identical; the assertion is the issue's 1e-12 of each signal's peak.
"""

from __future__ import annotations

import shutil
import warnings
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from nativefmu.build import mingw_compiler
from nativefmu.container import ContainerError, export_fmu
from orchestrator import load_scenario, run_scenario

REPO = Path(__file__).resolve().parents[2]
RTOL = 1e-12
TRUSS = ["truss10_structure", "piezo_p243_40", "piezo_p243_30", "controller_truss10_strain_diag",
         "controller_truss10_strain_long", "excitation"]
EOS = ["eos_testbed_structure", "acs", "disturbance", "piezo_p845_37",
       "controller_testbed_isolation", "controller_eos_isolation"]
EOS_ON = ["dist_swir.preset=swir_cryocooler", "dist_rwa.preset=rwa",
          "dist_vnir.preset=vnir_pointing", "dist_ceres.preset=ceres_scan",
          "ctrl_iso1.gain=0.27", "ctrl_iso2.gain=0.27", "ctrl_iso3.gain=0.27",
          "ctrl_swir.gain=0.1", "ctrl_vnir.gain=0.1"]
MIXED = """
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
[fmus.excitation]
fmu = "excitation"
period = 0.1
parameters = { amp1 = 10.0, freq1 = 3.0, t_stop = 1.0 }
[[connections]]
from = "structure.strain_diag"
to = "ctrl_diag.y1"
[[connections]]
from = "excitation.v1"
to = "ctrl_diag.r1"
[[connections]]
from = "ctrl_diag.u1"
to = "piezo_diag.v_cmd"
[[connections]]
from = "piezo_diag.force"
to = "structure.fc_diag"
[[connections]]
from = "structure.elong_diag"
to = "piezo_diag.elongation"
[[actions]]
time = 0.7
set = { "ctrl_diag.enable" = false }
[record]
variables = ["structure.strain_diag", "ctrl_diag.u1", "piezo_diag.voltage",
             "piezo_diag.force", "structure.los_tip_pitch"]
"""


def _quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kw)


@pytest.fixture(scope="module")
def fmu_dir(suite_fmus, suite_fmu_dir):
    suite_fmus(*TRUSS, *EOS)
    return suite_fmu_dir


@pytest.fixture(scope="module")
def cases(fmu_dir, tmp_path_factory, suite_container):
    """name -> (scenario, master table, container FMU).  The truss's is the run's
    (``jitterfmu export-fmu``, win64 too with mingw-w64, which one test reads); the EOS
    and mixed ones have their Linux binary only (no test reads another)."""
    tmp = tmp_path_factory.mktemp("container")
    (tmp / "mixed.toml").write_text(MIXED)
    truss = REPO / "scenarios" / "truss10_closed_loop.toml"
    scenarios = {
        "truss": load_scenario(truss),
        "eos": load_scenario(REPO / "scenarios" / "eos_budget.toml").with_overrides(EOS_ON),
        "mixed": load_scenario(tmp / "mixed.toml"),
    }
    stops = {"truss": 12.0, "eos": 1.0, "mixed": 1.2}
    out = {}
    for name, sc in scenarios.items():
        table, meta = _quiet(run_scenario, sc, stop_time=stops[name], fmu_dir=fmu_dir)
        assert meta["status"] == "ok"
        fmu = suite_container(truss, 2) if name == "truss" else \
            _quiet(export_fmu, sc, tmp / f"{name}.fmu", fmu_dir=fmu_dir, windows=False)
        out[name] = (sc, table, fmu, stops[name])
    return out


def _compare(table, times, values, names, base):
    """Max over signals of |container - master| / peak at the common instants."""
    tm = np.rint(np.asarray(table["time"]) / base).astype(np.int64)
    tc = np.rint(np.asarray(times) / base).astype(np.int64)
    common, ia, ic = np.intersect1d(tm, tc, return_indices=True)
    assert len(common) >= min(len(tm), len(tc)) - 1
    worst, moving = 0.0, 0
    for j, ref in enumerate(names):
        a = np.asarray(table[ref], float)[ia]
        b = np.asarray(values[j], float)[ic]
        peak = np.max(np.abs(a))
        if peak == 0:   # a flag never set: the container must agree exactly
            assert np.all(b == 0), ref
            continue
        moving += 1
        worst = max(worst, np.max(np.abs(a - b)) / peak)
    assert moving >= len(names) // 2, "most signals are zero: nothing compared"
    return worst


@pytest.mark.parametrize("name", ["truss", "eos", "mixed"])
@pytest.mark.parametrize("mult", [1, 4])
def test_fmpy_steps_the_container_as_the_master_runs(cases, name, mult):
    """fmpy.simulate_fmu at the base step and at 4x it: the master's table."""
    sc, table, fmu, stop = cases[name]
    base = float(sc.experiment.output_interval) if name != "truss" else 1e-3
    res = fmpy.simulate_fmu(str(fmu), stop_time=stop, output_interval=mult * base,
                            output=list(sc.record))
    worst = _compare(table, res["time"], [res[r] for r in sc.record], sc.record, base)
    assert worst <= RTOL


@pytest.mark.parametrize("name", ["truss", "eos"])
def test_plain_c_host_steps_the_container_as_the_master_runs(cases, name, tmp_path):
    """tests/support/c_host under ``env -i`` (no Python in the process)."""
    from tests.support.hosts import compile_c_host, run_c_host

    sc, table, fmu, stop = cases[name]
    real = list(sc.record)
    n = int(round(stop / 1e-3)) // 2
    y = run_c_host(fmu, outputs=real, step_size=2e-3, n_steps=n,
                   host=compile_c_host(tmp_path / "host"), wrapper=["env", "-i"])
    times = 2e-3 * np.arange(1, n + 1)
    assert _compare(table, times, y.T, real, 1e-3) <= RTOL


def test_a_step_of_one_and_a_half_base_ticks_is_an_error(cases):
    """An FMI error naming the allowed steps, not a wrong answer."""
    sc, _, fmu, _ = cases["truss"]
    with pytest.raises(Exception, match="status 3"):
        fmpy.simulate_fmu(str(fmu), stop_time=0.03, output_interval=1.5e-3)


def test_state_round_trip_mid_run_equals_the_uninterrupted_run(cases, tmp_path):
    """Save at 0.25 s (serialised bytes), run on, restore, run again: same outputs; a
    flipped byte is refused and changes nothing."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    sc, _, fmu, _ = cases["mixed"]
    md = read_model_description(str(fmu))
    vrs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu), str(tmp_path / "x")),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="c")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    h = 1e-3
    for k in range(250):
        s.doStep(k * h, h)
    saved = bytes(s.serializeFMUstate(s.getFMUstate()))

    def run_on(k0):
        rows = []
        for k in range(k0, k0 + 700):
            s.doStep(k * h, h)
            rows.append(s.getReal(vrs))
        return np.array(rows)
    first = run_on(250)
    assert np.max(np.abs(first)) > 0
    bad = bytearray(saved)
    bad[len(bad) // 2] ^= 0x10
    with pytest.raises(Exception):
        s.setFMUstate(s.deSerializeFMUstate(bytes(bad)))
    s.setFMUstate(s.deSerializeFMUstate(saved))
    np.testing.assert_array_equal(run_on(250), first)
    s.terminate()
    s.freeInstance()


def test_fmpy_validation_passes_and_model_structure_is_exact(cases):
    """fmpy's validation finds nothing; the truss's outputs depend on no input (all
    inputs are driven), and a parameter shows in its outputs' initial dependencies."""
    sc, _, fmu, _ = cases["truss"]
    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu))
    assert [v.causality for v in md.modelVariables].count("output") == len(sc.record)
    assert all(u.dependencies == [] for u in md.outputs)


def test_exposed_parameter_and_dependencies(fmu_dir, tmp_path):
    """--parameter ctrl_diag.gain becomes a parameter whose value changes the run; with
    ctrl_diag.r1 left free, the law's D_c path makes u1 depend on it in the same step,
    and setting r1 moves u1 at once, without a step.  The amplifier reads u1 as the
    master does for a connection it does not order (graph.feedthrough_edges: u1 depends
    on no connected input), the value stamped <= t_k, so force does not depend on r1."""
    from fmpy import extract
    from fmpy.fmi2 import FMU2Slave

    path = _quiet(export_fmu, _mixed(tmp_path), tmp_path / "p.fmu", parameters=["ctrl_diag.gain"],
                  fmu_dir=fmu_dir, windows=False)
    md = fmpy.read_model_description(str(path))
    by = {v.name: v for v in md.modelVariables}
    assert by["ctrl_diag.gain"].causality == "parameter"
    assert by["ctrl_diag.gain"].start is not None
    assert validate_fmu(str(path)) == []
    runs = [fmpy.simulate_fmu(str(path), stop_time=0.6, output_interval=1e-3,
                              start_values={"ctrl_diag.gain": g, "ctrl_diag.r1": 20.0},
                              output=["ctrl_diag.u1"])
            for g in (1.0, 0.5)]
    assert np.max(np.abs(runs[0]["ctrl_diag.u1"] - runs[1]["ctrl_diag.u1"])) > 0
    init = {u.variable.name: {d.name for d in u.dependencies} for u in md.initialUnknowns}
    assert "ctrl_diag.gain" in init["ctrl_diag.u1"]
    step = {u.variable.name: {d.name for d in u.dependencies} for u in md.outputs}
    assert step["ctrl_diag.u1"] == {"ctrl_diag.r1"}
    assert step["piezo_diag.force"] == set()
    assert step["structure.strain_diag"] == set() == step["piezo_diag.voltage"]
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path), str(tmp_path / "x")),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="c")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    for k in range(400):
        s.doStep(k * 1e-3, 1e-3)
    u1, r1 = by["ctrl_diag.u1"].valueReference, by["ctrl_diag.r1"].valueReference
    before = s.getReal([u1])[0]
    s.setReal([r1], [50.0])
    after = s.getReal([u1])[0]
    s.terminate()
    s.freeInstance()
    assert after != before


def _mixed(tmp_path):
    p = tmp_path / "mixed.toml"
    p.write_text(MIXED.replace('[[actions]]\ntime = 0.7\nset = { "ctrl_diag.enable" = false }\n',
                               "").replace('[[connections]]\nfrom = "excitation.v1"\nto = "ctrl_diag.r1"\n',
                                           ""))
    return p


def test_export_refuses_a_python_fmu_in_one_sentence(fmu_dir, tmp_path, suite_fmus):
    suite_fmus(*TRUSS, kind="python")
    sc = load_scenario(REPO / "scenarios" / "truss10_closed_loop.toml")
    with pytest.raises(ContainerError, match=r"^structure \(truss10_structure\.fmu: a Python "
                       r"FMU\).*cannot go into a native container FMU; build the native"):
        _quiet(export_fmu, sc, tmp_path / "x.fmu", fmu_dir=fmu_dir / "python")


def test_export_refuses_a_third_party_fmu(fmu_dir, tmp_path):
    """An FMU generated by another tool (its modelDescription says so) is named."""
    foreign = tmp_path / "fmus"
    foreign.mkdir()
    for name in TRUSS:
        shutil.copy2(fmu_dir / f"{name}.fmu", foreign / f"{name}.fmu")
    src = foreign / "excitation.fmu"
    with zipfile.ZipFile(fmu_dir / "excitation.fmu") as zin, \
            zipfile.ZipFile(src, "w") as zout:
        for item in zin.namelist():
            data = zin.read(item)
            if item == "modelDescription.xml":
                data = data.replace(b'generationTool="jitterfmu nativefmu',
                                    b'generationTool="OtherTool 3')
            zout.writestr(item, data)
    sc = load_scenario(REPO / "scenarios" / "truss10_closed_loop.toml")
    with pytest.raises(ContainerError, match=r"excitation \(excitation\.fmu: not a jitterfmu "
                       r"native FMU \(generated by OtherTool 3"):
        _quiet(export_fmu, sc, tmp_path / "x.fmu", fmu_dir=foreign)


def test_export_refuses_unknown_and_unexposable_parameters(fmu_dir, tmp_path):
    sc = load_scenario(REPO / "scenarios" / "truss10_closed_loop.toml")
    with pytest.raises(ContainerError, match=r"--parameter ctrl_diag.gian: instance "
                       r"'ctrl_diag' has no parameter 'gian'.*gain"):
        _quiet(export_fmu, sc, tmp_path / "x.fmu", parameters=["ctrl_diag.gian"],
               fmu_dir=fmu_dir)
    with pytest.raises(ContainerError, match=r"no instance 'ctrl_dag'"):
        _quiet(export_fmu, sc, tmp_path / "x.fmu", parameters=["ctrl_dag.gain"],
               fmu_dir=fmu_dir)
    with pytest.raises(ContainerError, match=r"--parameter ctrl_diag.y1: .*no parameter"):
        _quiet(export_fmu, sc, tmp_path / "x.fmu", parameters=["ctrl_diag.y1"],
               fmu_dir=fmu_dir)


@pytest.mark.long   # make test-full: exports a container, 7 s
def test_a_fixed_string_parameter_is_exposed_and_a_tunable_one_refused(fmu_dir, tmp_path):
    """--parameter dist.preset (a fixed String: set before initialisation) works and
    changes the run; a tunable String is refused in one sentence (the container's state
    carries no strings), shown on the plan with that variable made tunable."""
    from dataclasses import replace

    from nativefmu.container import _checked_plan, _variables

    p = tmp_path / "s.toml"
    text = MIXED.replace("[[actions]]", '[fmus.dist]\nfmu = "disturbance"\nperiod = 1e-3\n'
                         '[[connections]]\nfrom = "dist.Fx"\nto = "structure.f_tip_x"\n'
                         "[[actions]]")
    p.write_text(text)
    sc = load_scenario(p)
    path = _quiet(export_fmu, sc, tmp_path / "s.fmu", parameters=["dist.preset"],
                  fmu_dir=fmu_dir, windows=False)
    md = fmpy.read_model_description(str(path))
    v = next(x for x in md.modelVariables if x.name == "dist.preset")
    assert (v.type, v.causality, v.start) == ("String", "parameter", "none")
    plan = _quiet(_checked_plan, sc, None, fmu_dir)
    info = plan.fmus["dist"]
    tunable = replace(info.variables["preset"], variability="tunable")
    plan2 = replace(plan, fmus={**plan.fmus, "dist": replace(
        info, variables={**info.variables, "preset": tunable})})
    with pytest.raises(ContainerError, match=r"^--parameter dist.preset is a tunable String, "
                       r"which a container cannot expose .*; set it in the scenario instead$"):
        _variables(plan2, None, ["dist.preset"])


@pytest.mark.skipif(mingw_compiler() is None, reason="x86_64-w64-mingw32-gcc is not "
                    "installed (make native-deps); the win64 binary is not built")
def test_win64_binary_exports_the_fmi_functions(cases, tmp_path):
    _, _, fmu, _ = cases["truss"]
    with zipfile.ZipFile(fmu) as z:
        dll = tmp_path / "c.dll"
        dll.write_bytes(z.read(f"binaries/win64/{fmu.stem}.dll"))
        names = z.namelist()
    assert dll.read_bytes()[:2] == b"MZ"
    import subprocess
    dump = subprocess.run(["x86_64-w64-mingw32-objdump", "-p", str(dll)], capture_output=True,
                          text=True).stdout
    for fn in ("fmi2DoStep", "fmi2Instantiate", "fmi2SerializeFMUstate"):
        assert f"] {fn}\n" in dump or f" {fn}\n" in dump
    assert "sources/container.c" in names and "sources/fastloop.c" in names


def test_linux_binary_needs_only_libc_and_libm(cases, tmp_path):
    import subprocess

    _, _, fmu, _ = cases["eos"]
    lib = tmp_path / "e.so"
    with zipfile.ZipFile(fmu) as z:
        lib.write_bytes(z.read("binaries/linux64/eos.so"))
    needed = subprocess.run(["objdump", "-p", str(lib)], capture_output=True, text=True).stdout
    libs = {line.split()[1] for line in needed.splitlines() if line.strip().startswith("NEEDED")}
    assert libs <= {"libc.so.6", "libm.so.6"}, libs
    assert str(REPO).encode() not in lib.read_bytes()
