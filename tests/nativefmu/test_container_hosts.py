"""The container FMU under hosts that nobody here wrote, as they step.

fmuCheck (FMIL 2.0.3) accumulates ``t += h`` and shortens its last step to land on the
stop time: at ``-s 8`` its last step is 1 ms less 1e-12 s (1e-9 of the step, just outside
the container's earlier tolerance), at ``-s 12`` its time falls 1.2e-12 s short and it
takes one more step of 1.2e-12 s.  Its loop is reproduced here (the host under test) on
the FMI 2.0 and FMI 3.0 containers of the truss: every step is taken and the outputs are
the master's table bit for bit; a step of 1.5 base ticks is still refused.  A forged
state whose tick is INT64_MAX is refused (its time would wrap), and a step of 1e15 s
returns at once with an error.
"""

from __future__ import annotations

import shutil
import struct
import warnings

import numpy as np
import pytest
from fmpy import extract, read_model_description

from orchestrator import load_scenario, run_scenario

from .test_container_fmi3 import REPO, _assert_master_table

pytestmark = pytest.mark.slow

STOPS = (8.0, 12.0)


def test_export_fmu_says_when_it_starts_and_then_what_it_wrote(containers):
    """The command compiles for seconds: a start line naming the scenario, what it
    writes and the FMI version first, the file written last, and between them only the
    one line on the truss's unconnected inputs."""
    for fmi, fmu in containers[0].items():
        lines = fmu.with_suffix(".said").read_text().splitlines()
        assert len(lines) == 3, lines
        assert lines[0].startswith("jitterfmu: export-fmu '") and lines[0].endswith(
            f" (FMI {fmi}.0)"), lines
        assert "truss10_closed_loop.toml': compiling its native FMUs and the master's " \
            "schedule into '" in lines[0]
        assert lines[1].startswith("jitterfmu: warning: 4 inputs are not connected"), lines
        assert lines[2].startswith("wrote ") and lines[2].endswith(fmu.name), lines


def fmucheck_steps(stop, h=1e-3):
    """FMIL fmuCheck's co-simulation loop: ``(t, h)`` of every doStep."""
    t, out = 0.0, []
    while t < stop:
        step = stop - t if t + h > stop else h
        out.append((t, step))
        t += step
    return out


@pytest.fixture(scope="module")
def containers(suite_container, suite_fmu_dir):
    """{fmi: container FMU} of the truss closed loop (the run's, by ``jitterfmu
    export-fmu``), and the master's table over 12 s."""
    path = REPO / "scenarios" / "truss10_closed_loop.toml"
    out = {fmi: suite_container(path, fmi) for fmi in (2, 3)}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sc = load_scenario(path)
        table, meta = run_scenario(sc, stop_time=max(STOPS), fmu_dir=suite_fmu_dir)
    assert meta["status"] == "ok"
    return out, sc, table


class Slave:
    """An fmpy slave of either FMI version with one interface: do_step, get, state."""

    def __init__(self, fmu, fmi):
        from fmpy.fmi2 import FMU2Slave
        from fmpy.fmi3 import FMU3Slave

        md = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.unzip = extract(str(fmu))
        self.fmi = fmi
        self.log = []
        cls = FMU2Slave if fmi == 2 else FMU3Slave
        self.s = cls(guid=md.guid, unzipDirectory=self.unzip, instanceName="h",
                     modelIdentifier=md.coSimulation.modelIdentifier)
        if fmi == 2:
            self.s.instantiate(loggingOn=True)
            self.s.setupExperiment(startTime=0.0)
            self.s.enterInitializationMode()
        else:
            self.s.instantiate(logMessage=lambda env, st, cat, msg: self.log.append(
                msg.decode() if isinstance(msg, bytes) else str(msg)))
            self.s.enterInitializationMode(startTime=0.0)
        self.s.exitInitializationMode()

    def do_step(self, t, h):
        self.s.doStep(t, h)

    def get(self, names):
        vrs = [self.vr[n] for n in names]
        return self.s.getReal(vrs) if self.fmi == 2 else self.s.getFloat64(vrs)

    def state(self):
        if self.fmi == 2:
            st = self.s.getFMUstate()
            return bytearray(self.s.serializeFMUstate(st))
        st = self.s.getFMUState()
        return bytearray(self.s.serializeFMUState(st))

    def restore(self, blob):
        if self.fmi == 2:
            return self.s.setFMUstate(self.s.deSerializeFMUstate(bytes(blob)))
        return self.s.setFMUState(self.s.deserializeFMUState(bytes(blob)))

    def close(self):
        self.s.terminate()
        self.s.freeInstance()
        shutil.rmtree(self.unzip, ignore_errors=True)


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("stop", STOPS)
def test_fmuchecks_drifting_last_step_is_taken_and_gives_the_masters_table(
        containers, fmi, stop):
    fmus, sc, table = containers
    steps = fmucheck_steps(stop)
    assert steps[-1][1] != 1e-3        # the host's last step is not the base step
    names = list(sc.record)
    s = Slave(fmus[fmi], fmi)
    try:
        times, rows = [], []
        for t, h in steps:
            s.do_step(t, h)
            if h > 0.5e-3:             # fmuCheck records after each real step
                times.append(round(t + h, 9))
                rows.append(s.get(names))
    finally:
        s.close()
    assert len(times) == round(stop / 1e-3)
    # the master records every 4 ms: compare there
    keep = [i for i, t in enumerate(times) if round(t * 1000) % 4 == 0]
    rows = np.array(rows)[keep]
    _assert_master_table(table, np.array(times)[keep], rows.T, names)


@pytest.mark.parametrize("fmi", [2, 3])
def test_one_and_a_half_ticks_and_a_step_of_1e15_s_are_refused_at_once(containers, fmi):
    from fmpy.fmi1 import FMICallException

    fmus, _, _ = containers
    s = Slave(fmus[fmi], fmi)
    try:
        for h in (1.5e-3, 1e15):
            with pytest.raises(FMICallException):
                s.do_step(0.0, h)
        s.do_step(0.0, 1e-3)           # the instance steps on
    finally:
        s.close()


def _fnv1a(data: bytes) -> int:
    x = 0xcbf29ce484222325
    for b in data:
        x = ((x ^ b) * 0x100000001b3) & 0xFFFFFFFFFFFFFFFF
    return x


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("tick", [2**63 - 1, 2**53 + 1])
def test_a_forged_state_with_a_tick_past_exact_time_is_refused(containers, fmi, tick):
    from fmpy.fmi1 import FMICallException

    fmus, sc, _ = containers
    s = Slave(fmus[fmi], fmi)
    try:
        for k in range(3):
            s.do_step(k * 1e-3, 1e-3)
        blob = s.state()
        assert struct.unpack_from("<q", blob, 96)[0] == 3
        struct.pack_into("<q", blob, 96, tick)
        blob[-8:] = struct.pack("<Q", _fnv1a(bytes(blob[:-8])))
        with pytest.raises(FMICallException):
            s.restore(blob)
        s.do_step(3e-3, 1e-3)          # the state it had is kept
    finally:
        s.close()
