"""fmukit: the toy filter slave as a Python object, then as a built FMU in three hosts."""

import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))  # toyslave.py

from toyslave import ToyFilter  # noqa: E402

from fmutools.build import FmuSpec, build_fmu  # noqa: E402
from fmukit.modeldesc import check_model_description  # noqa: E402
from fmukit.units import ARCSEC_PER_RAD  # noqa: E402
from fmukit.slave import DeclarationError, FmuSlave, FmuStateError  # noqa: E402

OUTPUTS = ["y_state", "y_ft", "angle[1]", "angle[2]"]
_DEAD_INSTANCES = []  # instances after fmi2Fatal: never called or freed again
N = 100
H = 1e-3


def _inputs():
    rng = np.random.default_rng(7)
    return {"u": rng.standard_normal(N), "w[1]": rng.standard_normal(N), "w[2]": 0.3}


def _reference(a=0.9, b=0.1, d=0.5):
    """The filter recurrence written out independently of the slave."""
    inp = _inputs()
    u, w1, w2 = inp["u"], inp["w[1]"], np.full(N, inp["w[2]"])
    x = np.zeros(3)
    y = np.empty((N, 4))
    for k in range(N):
        x[0] = a * x[0] + b * u[k]
        x[1] = np.sin(x[0]) + 0.5 * x[1]
        x[2] = 0.99 * x[2] + 1e-3 * w2[k]
        y[k] = [x[0], x[0] + d * u[k], x[1] + w1[k], x[2]]
    return y


# ---------------------------------------------------------------- plain Python object
def test_slave_arrays_back_the_fmi_getters_and_setters():
    s = ToyFilter(instance_name="t")
    vr = {spec.name: spec.value_reference for spec in s.variable_specs}
    s.set_real([vr["w[1]"], vr["w[2]"]], [1.5, -2.0])
    np.testing.assert_array_equal(s.w, [1.5, -2.0])
    s.angle[:] = [3.0, 4.0]
    assert s.get_real([vr["angle[2]"], vr["angle[1]"]]) == [4.0, 3.0]
    s.u = 2.0
    assert s.get_real([vr["u"]]) == [2.0]
    with pytest.raises(TypeError, match="not a Real"):
        s.get_real([vr["gain_mode"]])
    s.set_integer([vr["gain_mode"]], [3])
    assert s.gain_mode == 3 and s.get_boolean([vr["enabled"]]) == [True]
    assert s.get_string([vr["label"]]) == ["toy"]


def test_two_instances_do_not_share_values():
    a, b = ToyFilter(instance_name="a"), ToyFilter(instance_name="b")
    a.u = 1.0
    assert b.u == 0.0 and type(a) is not type(b) and isinstance(a, ToyFilter)


def test_output_without_dependencies_is_rejected():
    class Bad(FmuSlave):
        def __init__(self, **kw):
            super().__init__(**kw)
            self.add_real("y", causality="output", unit="m")

        def do_step(self, t, h):
            return True

    with pytest.raises(DeclarationError, match="depends_on"):
        Bad(instance_name="bad")


def test_state_round_trip_covers_internal_arrays_bit_for_bit():
    s = ToyFilter(instance_name="t")
    s.u = 0.7
    for k in range(5):
        s.do_step(k * H, H)
    state = s._get_fmu_state()
    blob = ToyFilter._fmu_state_to_bytes(state)
    x_ref = s.x.copy()
    s.do_step(5 * H, H)
    first = s.get_real(list(range(9, 13)))
    for restored in (state, ToyFilter._fmu_state_from_bytes(blob)):
        s.do_step(6 * H, H)  # move away, then restore
        s._set_fmu_state(restored)
        np.testing.assert_array_equal(s.x, x_ref)
        assert s.n_steps == 5
        s.do_step(5 * H, H)
        assert s.get_real(list(range(9, 13))) == first


def test_serialized_state_refuses_pickles():
    import pickle

    with pytest.raises(FmuStateError, match="serialized FMU state is invalid"):
        ToyFilter._fmu_state_from_bytes(pickle.dumps({"real": __import__("os").system}))


def test_model_description_has_units_dependencies_and_initial_unknowns():
    root = ToyFilter(instance_name="t").to_xml()
    from xml.etree.ElementTree import tostring

    xml = tostring(root)
    assert check_model_description(xml) == []
    names = [sv.get("name") for sv in root.iter("ScalarVariable")]
    deps = {names[int(u.get("index")) - 1]: u.get("dependencies")
            for u in root.iterfind("ModelStructure/Outputs/Unknown")}
    pos = {n: str(i + 1) for i, n in enumerate(names)}
    assert deps == {"y_state": "", "y_ft": pos["u"], "angle[1]": pos["w[1]"], "angle[2]": ""}
    arcsec = root.find("UnitDefinitions/Unit[@name='rad']/DisplayUnit[@name='arcsec']")
    assert float(arcsec.get("factor")) == pytest.approx(ARCSEC_PER_RAD, rel=1e-15)
    assert root.find("CoSimulation").get("canGetAndSetFMUstate") == "true"


# ---------------------------------------------------------------- built FMU
@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    out = tmp_path_factory.mktemp("fmus")
    return build_fmu(FmuSpec("ToyFilterFmu", "toyslave:ToyFilter", description="toy filter"),
                     out)


@pytest.mark.slow
def test_built_fmu_validates_without_message(fmu):
    from fmutools.validate import validate_fmu

    assert validate_fmu(fmu) == []
    with zipfile.ZipFile(fmu) as zf:
        names = zf.namelist()
    assert "resources/fmuslave_ToyFilterFmu.py" in names
    assert "resources/fmukit/slave.py" in names and "resources/toyslave.py" in names
    assert "binaries/linux64/ToyFilterFmu_pythonfmu.so" in names


@pytest.mark.slow
def test_fmpy_run_matches_the_recurrence(fmu):
    from tests.support.hosts import run_fmpy

    y = run_fmpy(fmu, inputs=_inputs(), outputs=OUTPUTS, step_size=H, n_steps=N,
                 parameters={"a": 0.8})
    np.testing.assert_array_equal(y, _reference(a=0.8))


@pytest.mark.slow
def test_fmpy_get_set_and_serialized_state_reproduce_outputs_bit_for_bit(fmu):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    outs = [vr[n] for n in OUTPUTS]
    unzip = extract(str(fmu))
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier="ToyFilterFmu",
                  instanceName="s")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    u = _inputs()["u"]
    for k in range(10):
        s.setReal([vr["u"]], [u[k]])
        s.doStep(k * H, H)
    state = s.getFMUstate()
    blob = s.serializeFMUstate(state)

    def advance():
        rows = []
        for k in range(10, 20):
            s.setReal([vr["u"]], [u[k]])
            s.doStep(k * H, H)
            rows.append(s.getReal(outs))
        return np.array(rows)

    first = advance()
    s.setFMUstate(state)
    second = advance()
    restored = s.deSerializeFMUstate(blob)
    s.setFMUstate(restored)
    third = advance()
    np.testing.assert_array_equal(second, first)
    np.testing.assert_array_equal(third, first)
    assert np.any(first != 0.0)
    s.freeFMUstate(state)
    s.freeFMUstate(restored)
    s.terminate()
    s.freeInstance()


@pytest.mark.slow
def test_crafted_state_bytes_through_fmpy_run_nothing_and_fail_cleanly(fmu, tmp_path):
    """Issue 12: a pickle handed to fmi2DeSerializeFMUstate once ran a shell command."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    from test_state import crafted_pickle

    md = read_model_description(str(fmu))
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu), unzipdir=tmp_path / "x"),
                  modelIdentifier="ToyFilterFmu", instanceName="s")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    marker = tmp_path / "pwned"
    with pytest.raises(Exception, match="fmi2DeSerializeFMUstate failed with status 4"):
        s.deSerializeFMUstate(crafted_pickle(marker))
    assert not marker.exists()
    # fmi2Fatal: pythonfmu has freed the slave object, FMI 2.0 allows no further call
    # (not even fmi2FreeInstance), so the instance is kept, never touched again
    _DEAD_INSTANCES.append(s)


@pytest.mark.slow
def test_c_host_and_libcosim_reproduce_fmpy(fmu):
    from tests.support.hosts import run_c_host, run_fmpy, run_libcosim

    kw = dict(inputs=_inputs(), outputs=OUTPUTS, step_size=H, n_steps=N,
              parameters={"b": 0.2})
    y_fmpy = run_fmpy(fmu, **kw)
    # The C host runs in a subprocess whose environment has no PYTHONPATH, LD_PRELOAD
    # or VIRTUAL_ENV: the loader finds libpython and the venv on its own.
    np.testing.assert_array_equal(run_c_host(fmu, **kw), y_fmpy)
    np.testing.assert_allclose(run_libcosim(fmu, **kw), y_fmpy, rtol=1e-12, atol=0)


def _memcheck_errors(log: str) -> list[str]:
    """valgrind error blocks that involve a binary of the FMU (loader or pythonfmu)."""
    blocks, current = [], []
    for line in log.splitlines():
        text = line.split("== ", 1)[-1]
        if not text.strip():
            if current:
                blocks.append("\n".join(current))
            current = []
        else:
            current.append(text)
    kinds = ("Invalid read", "Invalid write", "Invalid free", "Mismatched free")
    return [b for b in blocks if b.startswith(kinds) and "binaries/linux64" in b]


@pytest.mark.long   # make test-full: valgrind, 7 s
@pytest.mark.slow
def test_c_host_run_is_clean_under_memcheck(fmu, tmp_path):
    """No invalid read, write or free in the FMU's binaries, exit handlers included.

    pythonfmu 0.7 resets its interpreter state twice at exit (static destructor, then
    library destructor) and so wrote to freed memory; the C host aborted now and then
    with "free(): corrupted unsorted chunks".  The loader releases the state first.
    """
    from tests.support.hosts import run_c_host, run_fmpy

    log = tmp_path / "memcheck.txt"
    kw = dict(inputs=_inputs(), outputs=OUTPUTS, step_size=H, n_steps=N, parameters={"b": 0.2})
    y = run_c_host(fmu, **kw, wrapper=["valgrind", f"--log-file={log}", "--num-callers=40"],
                   env={"PYTHONMALLOC": "malloc"})
    np.testing.assert_array_equal(y, run_fmpy(fmu, **kw))
    text = log.read_text()
    assert "ERROR SUMMARY" in text  # valgrind ran to the end of the process
    assert _memcheck_errors(text) == []


def test_build_while_the_same_fmu_runs_in_this_process(tmp_path):
    # An instance of the FMU running in this process leaves its slave module in
    # sys.modules under the name the build stages its script as; the build must still
    # inspect the staged script and ship the Linux binary, and leave the running one be.
    import types

    spec = FmuSpec("ToyFilterFmu", "toyslave:ToyFilter", description="toy filter")
    running = types.ModuleType(spec.module_name)   # stands for the in-process instance's
    sys.modules[spec.module_name] = running
    try:
        path = build_fmu(spec, tmp_path)
        with zipfile.ZipFile(path) as z:
            assert "binaries/linux64/ToyFilterFmu.so" in z.namelist()
        assert sys.modules[spec.module_name] is running
    finally:
        sys.modules.pop(spec.module_name, None)


def test_build_uses_the_installed_pythonfmu_after_an_fmu_bundled_one_was_loaded(tmp_path):
    # A pythonfmu FMU that ran in this process leaves its bundled pythonfmu (Python only,
    # no binaries) in sys.modules; a build must still use the installed one, and give the
    # running FMU its modules back.
    import types

    bundled = {n: types.ModuleType(n) for n in ("pythonfmu", "pythonfmu.builder")}

    class FmuBuilder:   # the bundled copy: building with it yields no binaries
        @staticmethod
        def build_FMU(*args, **kwargs):
            raise AssertionError("the bundled pythonfmu was used to build")

    bundled["pythonfmu.builder"].FmuBuilder = FmuBuilder
    bundled["pythonfmu.builder"].__file__ = str(tmp_path / "fmu" / "pythonfmu" / "builder.py")
    saved = {n: m for n, m in sys.modules.items() if n.split(".")[0] == "pythonfmu"}
    for n in saved:
        del sys.modules[n]
    sys.modules.update(bundled)
    try:
        path = build_fmu(FmuSpec("ToyFilterFmu", "toyslave:ToyFilter", description="toy"),
                         tmp_path)
        with zipfile.ZipFile(path) as z:
            assert "binaries/linux64/ToyFilterFmu.so" in z.namelist()
        assert sys.modules["pythonfmu.builder"] is bundled["pythonfmu.builder"]
    finally:
        for n in [n for n in sys.modules if n.split(".")[0] == "pythonfmu"]:
            del sys.modules[n]
        sys.modules.update(saved)


# ---------------------------------------------------------------- bounded steps
@pytest.mark.parametrize("h", [1e15, 0.0, -1e-3, float("nan"), float("inf")])
def test_a_step_longer_than_the_maximum_or_not_positive_is_refused_at_once(h):
    """Every slave's do_step is bounded (a controller looping over 2.5e17 samples of
    doStep(t, 1e15) never returned): refused with a logged sentence, nothing stepped."""
    from fmukit.slave import MAX_STEP

    s = ToyFilter(instance_name="t")
    before = s.y_state
    assert s.do_step(0.0, h) is False
    assert s.y_state == before
    assert [m.status.name for m in s.log_queue] == ["error"]
    assert f"expected a positive step of at most {MAX_STEP:g} s" in s.log_queue[0].msg
    assert s.do_step(0.0, 1e-3) is True       # a step within the bound is taken
