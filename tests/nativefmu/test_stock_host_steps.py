"""The piezo FMUs under fmuCheck's stepping: ``t += h``, the last step shortened to land
on the stop time.

fmuCheck (FMIL 2.0.3) at ``-s 8 -h 1e-3`` accumulated 7,999 steps and passed a last step
of 0.99999999899e-3 s, 1.0e-12 s short of the piezo's ``hold_step`` (at ``-s 12``: 1.2e-12 s
long): relatively 1.006e-9, just outside the 1e-9 the FMU accepted, so it ended with "was stepped by ... but its force
is the mean over hold_step" (both builds).  The host here steps the way fmuCheck's
``fmi2_cs_sim.c`` does.  Reference: the same FMU stepped at exact ``k h`` points.
"""

from __future__ import annotations

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from .test_host_time import exact_host, simulate

pytestmark = pytest.mark.slow

H = 1e-3
PIEZO = "piezo_p243_40"


def fmucheck_host(stop: float, h: float = H) -> list:
    """(start, size) of each step as fmuCheck takes them (fmi2_cs_sim.c)."""
    steps, t = [], 0.0
    while t < stop:
        size, t_next = h, t + h
        if t_next > stop - 1e-3 * h:   # the last step lands on the stop time
            size, t_next = stop - t, stop
        steps.append((t, size))
        t = t_next
    return steps


def _inputs(n: int) -> np.ndarray:
    k = np.arange(n)
    return np.column_stack([400 * np.sin(2 * np.pi * 8.4 * k * H),
                            1e-6 * np.sin(2 * np.pi * 9.5 * k * H)])


def test_the_host_is_fmuchecks():
    """The emulation gives fmuCheck's last steps: 1e-3 s less 1.0e-12 s after 7,999 steps
    to 8 s (the step in fmuCheck's message, 0.00099999999899402781), 1.2e-12 s more to 12 s."""
    for stop, off in ((8.0, 1.0059e-12), (12.0, -1.2109e-12)):
        steps = fmucheck_host(stop)
        assert len(steps) == int(stop / H)
        assert steps[-1][0] + steps[-1][1] == stop
        assert H - steps[-1][1] == pytest.approx(off, rel=1e-3)
    assert fmucheck_host(8.0)[-1][1] == float("0.00099999999899402781")


@pytest.mark.parametrize("kind", ["native", "python"])
@pytest.mark.parametrize("stop", [8.0, 12.0])
def test_piezo_runs_fmuchecks_steps_as_exact_ones(suite_fmus, kind, stop):
    """Every step OK, the force and strain those of the exact host to 1e-12 of peak."""
    path = suite_fmus(PIEZO, kind=kind)[PIEZO]
    steps = fmucheck_host(stop)
    u = _inputs(len(steps))
    y = simulate(path, {}, u, steps)
    ref = simulate(path, {}, u, exact_host(len(steps)))
    peak = np.max(np.abs(ref), axis=0)
    assert np.all(peak[:2] > 0)
    peak[peak == 0] = 1.0
    assert np.max(np.abs(y - ref) / peak) <= 1e-12


@pytest.mark.parametrize("kind", ["native", "python"])
@pytest.mark.parametrize("size", [1.5 * H, H * (1 + 3e-9)])
def test_a_step_that_is_not_hold_step_is_still_refused(suite_fmus, kind, size):
    """1.5 steps, and 3e-9 off at the first step (no time accumulated there yet)."""
    path = suite_fmus(PIEZO, kind=kind)[PIEZO]
    with pytest.raises(FMICallException):
        simulate(path, {}, _inputs(2), [(0.0, H), (H, size)])
