"""The sine-burst excitation and its FMU."""

import numpy as np
import pytest

from distfmu.excitation import sine_burst


def test_sine_burst_window_and_values():
    t = np.arange(0, 2, 1e-3)
    v = sine_burst(t, 3.0, 8.4, 0.5, 1.5)
    assert np.all(v[t < 0.5] == 0) and np.all(v[t >= 1.5] == 0)
    on = (t >= 0.5) & (t < 1.5)
    np.testing.assert_allclose(v[on], 3.0 * np.sin(2 * np.pi * 8.4 * (t[on] - 0.5)))


@pytest.mark.slow
def test_excitation_fmu(tmp_path):
    from fmpy.validation import validate_fmu

    from distfmu.fmuspec import specs
    from fmutools.build import build_fmu
    from tests.support.hosts import run_c_host, run_fmpy
    fmu = build_fmu(specs(["excitation"])[0], tmp_path)
    assert validate_fmu(str(fmu)) == []
    kw = dict(outputs=["v1", "v2"], step_size=1e-3, n_steps=300,
              parameters={"amp1": 2.0, "freq1": 8.4, "amp2": 1.0, "freq2": 9.5,
                          "t_stop": 0.2})
    y = run_fmpy(fmu, **kw)
    t = np.arange(1, 301) * 1e-3
    np.testing.assert_allclose(y[:, 0], sine_burst(t, 2.0, 8.4, 0.0, 0.2), atol=1e-15)
    np.testing.assert_allclose(y[:, 1], sine_burst(t, 1.0, 9.5, 0.0, 0.2), atol=1e-15)
    np.testing.assert_array_equal(run_c_host(fmu, **kw), y)
