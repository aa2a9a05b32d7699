"""Native FMU state: a refused state changes nothing, non-finite values are refused.

The bytes are edited as a hostile or buggy host would, with the layout's FNV-1a 64
checksum recomputed (layout at the top of ``fmi2.c``), so that only the check under
test can refuse them.
"""

import shutil
import struct

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

pytestmark = pytest.mark.slow

MODEL = "controller_eos_isolation"
H = 1e-3
REALS = 104                      # offset of the Real values in the layout


def fnv1a(data: bytes) -> int:
    h = 0xcbf29ce484222325
    for b in data:
        h = ((h ^ b) * 0x100000001b3) & 0xFFFFFFFFFFFFFFFF
    return h


def reseal(blob: bytearray) -> bytes:
    blob[-8:] = struct.pack("<Q", fnv1a(bytes(blob[:-8])))
    return bytes(blob)


@pytest.fixture
def pair(suite_fmus):
    """Two instances of the native controller stepped alike, and its variables."""
    path = suite_fmus(MODEL)[MODEL]
    md = read_model_description(str(path))
    unzipped = extract(str(path))
    fmus = []
    for name in ("a", "b"):
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, instanceName=name,
                        modelIdentifier=md.coSimulation.modelIdentifier)
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        fmus.append(fmu)
    yield fmus, {v.name: v.valueReference for v in md.modelVariables}
    for fmu in fmus:
        fmu.terminate()
        fmu.freeInstance()
    shutil.rmtree(unzipped, ignore_errors=True)


def steps(fmu, vr, y, k0):
    out = []
    for k, value in enumerate(y, start=k0):
        fmu.setReal([vr["y1"]], [float(value)])
        fmu.doStep(k * H, H)
        out.append(fmu.getReal([vr["u1"]])[0])
    return np.array(out)


def saved(fmu):
    state = fmu.getFMUstate()
    blob = bytearray(fmu.serializeFMUstate(state))
    fmu.freeFMUstate(state)
    return blob


def test_a_state_the_kernel_refuses_changes_nothing(pair):
    """Limits crossed in the saved state (u_min > u_max): the controller's own check
    refuses it after the bytes passed, and the instance goes on as if never restored."""
    (a, b), vr = pair
    y = np.random.default_rng(3).standard_normal(60)
    steps(a, vr, y[:20], 0)
    steps(b, vr, y[:20], 0)
    blob = saved(a)
    struct.pack_into("<d", blob, REALS + 8 * vr["u_min"], 5.0)
    struct.pack_into("<d", blob, REALS + 8 * vr["u_max"], -5.0)
    state = a.deSerializeFMUstate(reseal(blob))
    with pytest.raises(Exception, match="fmi2SetFMUstate"):
        a.setFMUstate(state)
    a.freeFMUstate(state)
    assert a.getReal([vr["u_min"], vr["u_max"]]) == b.getReal([vr["u_min"], vr["u_max"]])
    np.testing.assert_array_equal(steps(a, vr, y[20:], 20), steps(b, vr, y[20:], 20))


@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_a_non_finite_real_value_in_a_state_is_refused(pair, value):
    (a, _), vr = pair
    steps(a, vr, np.ones(5), 0)
    blob = saved(a)
    struct.pack_into("<d", blob, REALS + 8 * vr["y1"], value)
    with pytest.raises(Exception, match="fmi2DeSerializeFMUstate"):
        a.deSerializeFMUstate(reseal(blob))
