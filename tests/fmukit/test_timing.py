"""Communication points robust to the host's time arithmetic (fmukit.timing).

Reference: the exact tick times ``k / 1000`` (Python's correctly rounded division), and
the disturbance FMUs (native and Python) stepped as three kinds of host step them.
"""

from fractions import Fraction

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from fmukit.timing import end_time


def _hosts(n, h):
    """(start, step) pairs of n steps as three hosts pass them."""
    exact = [(k * h, h) for k in range(n)]                        # t_k and the period
    fmpy_like = [(k * h, (k + 1) * h - k * h) for k in range(n)]  # (k+1)h - kh
    acc, t = [], 0.0
    for _ in range(n):
        acc.append((t, h))                                         # t += h
        t += h
    return {"t_k + h": exact, "(k+1)h - kh": fmpy_like, "t += h": acc}


def test_every_host_gets_the_exact_tick():
    n, h = 20000, 1e-3
    want = [float(Fraction(k + 1, 1000)) for k in range(n)]
    for name, steps in _hosts(n, h).items():
        last, got = 0.0, []
        for t, step in steps:
            last = end_time(t, step, last)
            got.append(last)
        assert got == want, name
    # without the previous end, t_k + h alone misses 1 tick in 3 by an ulp
    raw = [t + s for t, s in _hosts(n, h)["t_k + h"]]
    assert sum(a != b for a, b in zip(raw, want)) > n // 4


def test_a_drifting_clock_is_brought_back_to_the_microsecond():
    """A host whose clock is k h - 1e-12 k / n s: its steps are h - 1.25e-16 s, more than
    rounding off 1 ms, yet the chain of communication points stays on k / 1000."""
    n, h, drift = 8000, 1e-3, -1e-12
    t = [k * h + drift * k / n for k in range(n + 1)]
    last, got = 0.0, []
    for k in range(n):
        last = end_time(t[k], t[k + 1] - t[k], last)
        got.append(last)
    assert got == [float(Fraction(k + 1, 1000)) for k in range(n)]
    # but a time a real fraction of a step from the microsecond is not moved
    assert end_time(0.0, 1e-3 + 1e-8) == 1e-3 + 1e-8


def test_a_time_off_the_grid_is_left_alone():
    t, h = 1.0 / 3.0, 1.0 / 3.0
    assert end_time(t, h) == t + h
    assert end_time(0.0, 1e-3, last=5.0) == 1e-3          # a jump: the host's time wins


@pytest.mark.parametrize("kind", ["native", "python"])
def test_disturbance_fmu_gives_one_answer_under_every_host(suite_fmus, kind):
    """A slew whose acceleration ends at 1.05 s: one sample of it early or late is 2 %
    of its impulse; every host must see the same samples."""
    from distfmu.slave import DisturbanceSlave

    path = suite_fmus("disturbance", kind=kind)["disturbance"]
    md = read_model_description(path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipped = extract(path)
    n, h = 1300, 1e-3
    runs = {}
    for host, steps in _hosts(n, h).items():
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, instanceName=host,
                        modelIdentifier=md.coSimulation.modelIdentifier)
        fmu.instantiate()
        fmu.setString([vr["preset"]], ["swir_pointing"])
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        out = []
        for t, step in steps:
            fmu.doStep(t, step)
            out.append(fmu.getReal([vr["Mx"]])[0])
        fmu.terminate()
        fmu.freeInstance()
        runs[host] = np.array(out)
    slave = DisturbanceSlave(instance_name="d", resources=None)
    slave.preset = "swir_pointing"
    exact = slave.series(np.array([float(Fraction(k + 1, 1000)) for k in range(n)]))[:, 3]
    assert np.count_nonzero(np.diff(exact)) >= 2   # the slew's edges are in the record
    for host, out in runs.items():
        np.testing.assert_array_equal(out, exact, err_msg=host)
