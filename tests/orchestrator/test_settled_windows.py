"""The testbed's before/after windows start on a settled response, by construction.

A synthetic boresight record (a steady 22 Hz line plus a 9.75 Hz transient decaying with
time constant ``tau``, as the testbed's lightly damped payload modes do) stands in for the
isolation-off co-simulation: the experiment must move its switch-on later until the record
changes by at most ``SETTLED_PCT`` between the two windows, and refuse when it never does.
"""

import numpy as np
import pytest

from orchestrator.experiments import testbed_isolation as ti


def _record(tau, amp=4.0):
    calls = []

    def run_off(t_on, stop):
        calls.append((t_on, stop))
        t = np.arange(0.0, stop + 1e-9, 1e-3)
        roll = np.sin(2 * np.pi * 22.0 * t) + amp * np.exp(-t / tau) * np.sin(2 * np.pi * 9.75 * t)
        return {"time": t, "structure.los_misr_roll": 1e-7 * roll,
                "structure.los_misr_pitch": np.zeros_like(t)}
    return run_off, calls


def _rms_analytic(tau, amp, t0, t1):
    # the two lines are orthogonal over a long window: mean square 1/2 + amp^2 e^(-2t/tau)/2
    t = np.linspace(t0, t1, 20001)
    return np.sqrt(np.mean(0.5 + 0.5 * amp ** 2 * np.exp(-2 * t / tau)))


def test_the_switch_on_moves_until_the_isolation_off_record_is_settled():
    tau = 3.0
    run_off, calls = _record(tau)
    off, t_on, stop, change = ti.settled_off_run(run_off, quick=True)
    # at 8.4 s the transient still changes the record by more than 2 %: moved once
    assert [c[0] for c in calls] == [ti.T_ON, ti.T_ON + ti.SETTLE_STEP]
    assert t_on == pytest.approx(ti.T_ON + ti.SETTLE_STEP)
    assert stop == pytest.approx(t_on + ti.AFTER[True] + ti.TAIL)
    w = ti.windows(t_on, stop)
    assert w["before"] == pytest.approx((t_on - 1.2, t_on))
    assert w["after"] == pytest.approx((stop - ti.TAIL - 1.2, stop - ti.TAIL))
    assert abs(change) <= ti.SETTLED_PCT
    # the change is the record's own, from its analytic mean square (the 5 Hz high-pass
    # passes both lines to within a fraction of a percent)
    want = 100 * (_rms_analytic(tau, 4.0, *w["after"]) / _rms_analytic(tau, 4.0, *w["before"]) - 1)
    assert change == pytest.approx(want, abs=0.1)
    first = ti.windows(ti.T_ON, calls[0][1])
    first_change = 100 * (_rms_analytic(tau, 4.0, *first["after"])
                          / _rms_analytic(tau, 4.0, *first["before"]) - 1)
    assert abs(first_change) > ti.SETTLED_PCT


def test_a_record_that_never_settles_is_refused_in_one_sentence():
    run_off, calls = _record(tau=100.0)
    with pytest.raises(RuntimeError, match=r"isolation off the boresight RMS still changes by "
                                           r"-\d+\.\d % between the windows"):
        ti.settled_off_run(run_off, quick=False)
    assert calls[-1][0] <= ti.MAX_T_ON + 1e-9 and len(calls) >= 2


def test_a_settled_record_keeps_the_first_switch_on():
    run_off, calls = _record(tau=0.5)
    _, t_on, _, change = ti.settled_off_run(run_off, quick=False)
    assert len(calls) == 1 and t_on == ti.T_ON and abs(change) < 0.5
