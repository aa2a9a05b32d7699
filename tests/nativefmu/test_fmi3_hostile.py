"""FMI 3.0 native FMUs against a hostile host.

A NaN or inf input gave NaN outputs with status OK; 1e300 gave outputs far outside the
declared range, still OK; a step from a wrong communication point (t + 0.5, -1) was taken
and time jumped; ``doStep(t, 1e15)`` never returned; the independent variable ``time``
could not be read (the stock FMI 3.0 hosts read every Float64 at initialisation).  Each
is refused with ``fmi3Error`` and one logged sentence naming the variable or the times,
and an instance that refused a bad call steps on as if it had never been made.
"""

from __future__ import annotations

import re
import shutil
import struct

import numpy as np
import pytest

from .test_fmi3 import dirs  # noqa: F401  (the FMI 3.0 builds of the session)

pytestmark = pytest.mark.slow

H = 1e-3


class Host:
    """One FMI 3.0 instance in fmpy, its variables by name and its logged messages."""

    def __init__(self, fmu):
        from fmpy import extract, read_model_description
        from fmpy.fmi3 import FMU3Slave

        md = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.reals = [v.valueReference for v in md.modelVariables
                      if v.type == "Float64" and v.name != "time"]
        self.unzip = extract(str(fmu))
        self.log = []
        self.s = FMU3Slave(guid=md.guid, unzipDirectory=self.unzip,
                           modelIdentifier=md.coSimulation.modelIdentifier, instanceName="h")
        self.s.instantiate(logMessage=lambda env, status, cat, msg: self.log.append(
            msg.decode() if isinstance(msg, bytes) else str(msg)))
        self.s.enterInitializationMode(startTime=0.0)
        self.s.exitInitializationMode()

    def refused(self, call, *args, **kw):
        """The call fails (fmi3Error) and logs one message; that message."""
        from fmpy.fmi1 import FMICallException

        n = len(self.log)
        with pytest.raises(FMICallException):
            call(*args, **kw)
        assert len(self.log) == n + 1
        return self.log[-1]

    def step(self, k, **inputs):
        if inputs:
            self.s.setFloat64([self.vr[n] for n in inputs], list(inputs.values()))
        self.s.doStep(currentCommunicationPoint=k * H, communicationStepSize=H)

    def close(self):
        self.s.terminate()
        self.s.freeInstance()
        shutil.rmtree(self.unzip, ignore_errors=True)


@pytest.fixture
def host(dirs):  # noqa: F811
    made = []

    def make(model):
        made.append(Host(dirs[3] / f"{model}.fmu"))
        return made[-1]
    yield make
    for h in made:
        h.close()


@pytest.mark.parametrize("model, name", [("truss10_structure", "fc_diag"),
                                         ("controller_truss10_strain_diag", "y1")])
@pytest.mark.parametrize("bad", [float("nan"), float("inf"), float("-inf")])
def test_a_non_finite_input_is_refused_and_nothing_is_set(host, model, name, bad):
    h = host(model)
    msg = h.refused(h.s.setFloat64, [h.vr[name]], [bad])
    assert msg == f"fmi3SetFloat64: {name} = {bad:g} is not a finite number; nothing was set"
    h.step(0)                         # the instance goes on, with the input unchanged
    assert np.isfinite(h.s.getFloat64([h.vr[name]])[0])


def test_an_input_driving_an_output_outside_its_range_is_an_error_not_ok(host):
    """1e300 N on the diagonal member: the strain output leaves its declared +-0.01 in
    the step; fmi3Error names the output, never the huge value with OK."""
    h = host("truss10_structure")
    h.s.setFloat64([h.vr["fc_diag"]], [1e300])
    msg = h.refused(h.step, 0)
    assert msg.startswith("fmi3DoStep: output ") and "outside its declared range" in msg


@pytest.mark.parametrize("model", ["truss10_structure", "controller_truss10_strain_diag",
                                   "excitation"])
@pytest.mark.parametrize("start", [7 * H + 0.5, -1.0, 6 * H, 8 * H])
def test_a_step_from_a_wrong_communication_point_is_refused(host, model, start):
    """Seven steps taken (t = 7 ms): a step from 0.507 s, -1 s, 6 ms or 8 ms is refused
    naming both times; the next right step gives what an undisturbed run gives."""
    a, b = host(model), host(model)
    name = [n for n in ("fc_diag", "y1") if n in a.vr]
    inputs = [{name[0]: 10.0 * np.sin(k)} if name else {} for k in range(12)]
    for k in range(7):
        a.step(k, **inputs[k])
        b.step(k, **inputs[k])
    msg = a.refused(a.s.doStep, currentCommunicationPoint=start, communicationStepSize=H)
    m = re.match(r"fmi3DoStep: the step starts at t = (\S+) s but the FMU is at t = (\S+) s; "
                 r"step from where the last step ended", msg)
    assert m and (float(m.group(1)), float(m.group(2))) == (start, 0.007), msg
    outs = a.reals
    for k in range(7, 12):
        a.step(k, **inputs[k])
        b.step(k, **inputs[k])
        assert a.s.getFloat64(outs) == b.s.getFloat64(outs)


def test_an_accumulating_hosts_clock_is_still_the_right_point(host):
    """t += h over 20,000 steps drifts by ulps: every step is still taken."""
    h = host("controller_truss10_strain_diag")
    t = 0.0
    for _ in range(20000):
        h.s.doStep(currentCommunicationPoint=t, communicationStepSize=H)
        t += H
    assert t != 20.0                    # the host's clock did drift
    assert h.s.getFloat64([h.vr["time"]]) == [20.0]


def test_a_step_longer_than_the_stated_maximum_is_refused_at_once(host):
    h = host("controller_truss10_strain_diag")
    msg = h.refused(h.s.doStep, currentCommunicationPoint=0.0, communicationStepSize=1e15)
    assert "longer than the 10000 s one step may take" in msg
    h.step(0)


@pytest.mark.parametrize("model", ["truss10_structure", "excitation"])
def test_time_is_read_as_the_current_time_and_cannot_be_set(host, model):
    h = host(model)
    assert h.s.getFloat64([h.vr["time"]]) == [0.0]
    for k in range(3):
        h.step(k)
    assert h.s.getFloat64([h.vr["time"]]) == [0.003]
    msg = h.refused(h.s.setFloat64, [h.vr["time"]], [5.0])
    assert "time is the independent variable and cannot be set" in msg


def _fnv1a(data: bytes) -> int:
    x = 0xcbf29ce484222325
    for b in data:
        x = ((x ^ b) * 0x100000001b3) & 0xFFFFFFFFFFFFFFFF
    return x


@pytest.mark.parametrize("forged", [float("inf"), 1e300, float("nan")])
def test_a_forged_state_time_is_refused_with_its_checksum_recomputed(host, forged):
    """The layout's last field before the checksum is the next communication point."""
    h = host("controller_truss10_strain_diag")
    for k in range(5):
        h.step(k)
    state = h.s.getFMUState()
    blob = bytearray(h.s.serializeFMUState(state))
    h.s.freeFMUState(state)
    assert struct.unpack_from("<d", blob, len(blob) - 16)[0] == 0.005
    struct.pack_into("<d", blob, len(blob) - 16, forged)
    blob[-8:] = struct.pack("<Q", _fnv1a(bytes(blob[:-8])))
    msg = h.refused(h.s.deserializeFMUState, bytes(blob))
    assert "FMU state rejected: its time" in msg
    h.step(5)


@pytest.mark.parametrize("model", ["truss10_structure", "piezo_p243_30", "piezo_p243_40",
                                   "controller_truss10_strain_diag",
                                   "controller_truss10_strain_long", "excitation", "acs",
                                   "disturbance", "eos_testbed_structure", "piezo_p845_37",
                                   "controller_eos_isolation", "controller_testbed_isolation"])
def test_a_host_that_reads_every_float64_as_fmusim_does_runs_every_fmu(dirs, model):  # noqa: F811
    """The stock Reference-FMUs fmusim (v0.0.39) reads every Float64 variable in
    initialisation mode and after each step, the independent variable ``time`` included
    (which the FMUs used to refuse: "value reference N is not a variable of this type").
    Its reads reproduced: all of them in one call, in the same phases; ``time`` reads the
    start time and then each step's end."""
    from fmpy import extract, read_model_description
    from fmpy.fmi3 import FMU3Slave

    fmu = dirs[3] / f"{model}.fmu"
    md = read_model_description(str(fmu))
    floats = [v.valueReference for v in md.modelVariables if v.type == "Float64"]
    t_vr = next(v.valueReference for v in md.modelVariables if v.causality == "independent")
    unzip = extract(str(fmu))
    s = FMU3Slave(guid=md.guid, unzipDirectory=unzip, instanceName="fmusim",
                  modelIdentifier=md.coSimulation.modelIdentifier)
    try:
        s.instantiate()
        s.enterInitializationMode(startTime=0.0)
        assert s.getFloat64([t_vr]) == [0.0]
        assert len(s.getFloat64(floats)) == len(floats)
        s.exitInitializationMode()
        for k in range(10):
            s.doStep(currentCommunicationPoint=k * H, communicationStepSize=H)
            values = dict(zip(floats, s.getFloat64(floats)))
            assert values[t_vr] == round((k + 1) * H, 12)
            assert all(np.isfinite(list(values.values())))
        s.terminate()
    finally:
        s.freeInstance()
        shutil.rmtree(unzip, ignore_errors=True)


@pytest.mark.parametrize("stop", [8.0, 12.0])
def test_fmuchecks_last_step_and_its_rounding_remainder_are_taken(host, stop):
    """fmuCheck adds t += h and shortens its last step to land on the stop time: at 8 s
    that step is 1 ms less 1e-12 s, at 12 s its time falls 1.2e-12 s short and it takes
    one more step of 1.2e-12 s (nothing to do: the FMU is already there).  The FMU's time
    is its own end plus the host's step (jf_end_time), so after the shortened step it
    stands within the host's 1e-12 s drift of the stop time."""
    from .test_container_hosts import fmucheck_steps

    h = host("controller_truss10_strain_diag")
    steps = fmucheck_steps(stop)
    for t, step in steps:
        h.s.doStep(currentCommunicationPoint=t, communicationStepSize=step)
    assert h.s.getFloat64([h.vr["time"]])[0] == pytest.approx(stop, rel=0, abs=2e-12)


@pytest.mark.parametrize("fmi", [2, 3])
def test_a_huge_finite_input_never_gives_nan_with_ok_under_either_fmi_version(
        dirs, suite_fmu_dir, fmi):  # noqa: F811
    """1.7e308 on the controller's strain input from t = 0: its state overflows and the
    command became NaN with status OK (FMI 2.0: u1 = 1000, nan, nan, ...).  Both builds
    now end that step with an error naming the output."""
    from fmpy import extract, read_model_description
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave

    model = "controller_truss10_strain_diag"
    fmu = (suite_fmu_dir if fmi == 2 else dirs[3]) / f"{model}.fmu"
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzip = extract(str(fmu))
    log = []
    cls = FMU2Slave if fmi == 2 else FMU3Slave
    s = cls(guid=md.guid, unzipDirectory=unzip, instanceName="h",
            modelIdentifier=md.coSimulation.modelIdentifier)
    try:
        if fmi == 2:
            s.instantiate(loggingOn=True)
            s.setReal([vr["t_on"]], [0.0])
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
            s.exitInitializationMode()
            s.setReal([vr["y1"]], [1.7e308])
            read = s.getReal
        else:
            s.instantiate(logMessage=lambda env, st, cat, msg: log.append(
                msg.decode() if isinstance(msg, bytes) else str(msg)))
            s.setFloat64([vr["t_on"]], [0.0])
            s.enterInitializationMode(startTime=0.0)
            s.exitInitializationMode()
            s.setFloat64([vr["y1"]], [1.7e308])
            read = s.getFloat64
        seen = []
        with pytest.raises(FMICallException):
            for k in range(50):
                s.doStep(k * 4e-3, 4e-3)
                seen.append(read([vr["u1"]])[0])
        assert seen and all(np.isfinite(seen))       # every step that said OK was finite
    finally:
        s.freeInstance()
        shutil.rmtree(unzip, ignore_errors=True)
    if fmi == 3:
        assert any(re.match(r"fmi3DoStep: output u1 = -?nan is not a finite number", m)
                   for m in log), log
