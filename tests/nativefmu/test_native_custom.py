"""Disturbance FMUs carrying their own table or band-limited random source: Python vs C.

The table is interpolated with numpy.interp's formula in C: the outputs are equal bit for
bit.  The random record is synthesised in C from the seed (numpy's PCG64 ported) by a
radix-2 inverse FFT where numpy uses pocketfft: equal to round-off (a few 1e-16 of the
peak), asserted at 1e-12.
"""

import numpy as np
import pytest

from distfmu.fmuspec import spec_with_source
from distfmu.sources import BandLimitedRandom, Sum, Table
from fmutools.build import build_fmu
from nativefmu.build import build_native
from nativefmu.data import NativeUnsupportedError, _term
from tests.nativefmu.test_native import WRENCH, assert_close, run

pytestmark = pytest.mark.slow

RNG = np.random.default_rng(5)
# samples from 0.3 s to about 1.2 s: the 2.8 s runs see both sides outside the range
TABLE = {fill: Table(0.3 + np.cumsum(RNG.uniform(0.005, 0.04, 40)),
                     RNG.standard_normal((40, 6)), fill=fill) for fill in ("zero", "hold")}
# a 2.048 s record: the 2.8 s runs wrap around it
RANDOM = BandLimitedRandom(psd_freqs=(0.0, 10.0, 60.0, 90.0), psd_values=(1e-4, 1e-3, 1e-3, 0.0),
                           seed=3, sample_rate=2000.0, n_samples=2**12,
                           direction=(0.3, 1.0, -0.2), kind="torque")
SOURCES = {"table_zero": TABLE["zero"], "table_hold": TABLE["hold"], "random": RANDOM,
           "mixed": Sum((TABLE["hold"], RANDOM))}


@pytest.fixture(scope="module")
def custom_fmus(tmp_path_factory):
    """{name: (native FMU, Python FMU)} of a disturbance FMU per source."""
    out = tmp_path_factory.mktemp("custom_disturbance")
    fmus = {}
    for name, source in SOURCES.items():
        spec = spec_with_source(source, f"dist_{name}")
        py = build_fmu(spec, out / "python", c_loader=False)
        fmus[name] = (build_native(spec, out, python_fmu=py, windows=False), py)
    return fmus


@pytest.mark.parametrize("name,seed", [("table_zero", 0), ("table_hold", 9), ("random", 0),
                                       ("random", 1), ("random", 12345), ("mixed", 7)])
def test_custom_source_equals_python(custom_fmus, name, seed):
    native_fmu, py_fmu = custom_fmus[name]
    kw = {"outputs": WRENCH, "step_size": 7e-3, "n_steps": 400,
          "parameters": {"seed": seed, "scale": 1.5, "stop_time": 2.5}}
    native, python = run(native_fmu, **kw), run(py_fmu, **kw)
    assert_close(native, python)
    if name.startswith("table"):
        np.testing.assert_array_equal(native, python)  # numpy.interp's formula: same bits
        outside = python[(np.arange(1, 401) * 7e-3 > 1.3) & (np.arange(1, 401) * 7e-3 < 2.5)]
        assert np.all(outside == 0) == (name == "table_zero") and np.any(python[20:100] != 0)
    assert np.all(python[-40:] == 0) and np.max(np.abs(python)) > 0


def test_seed_draws_another_record_and_presets_stay_reachable(custom_fmus):
    native_fmu, _ = custom_fmus["random"]
    kw = {"outputs": WRENCH, "step_size": 7e-3, "n_steps": 100}
    a = run(native_fmu, parameters={"seed": 1}, **kw)
    b = run(native_fmu, parameters={"seed": 2}, **kw)
    assert np.max(np.abs(a - b)) > 0.1 * np.max(np.abs(a))
    preset = run(native_fmu, parameters={"preset": "tir_cryocooler"}, **kw)
    assert np.max(np.abs(preset[:, 2])) > 0.1 and np.all(preset[:, 3:] == 0)


def test_native_refuses_a_record_length_that_is_not_a_power_of_two():
    with pytest.raises(NativeUnsupportedError, match="n_samples 3000 is not a power of two"):
        _term(BandLimitedRandom((0.0, 10.0), (1.0, 1.0), sample_rate=100.0, n_samples=3000))


@pytest.mark.parametrize("name,kind", [("table_zero", "Table"), ("random", "BandLimitedRandom"),
                                       ("mixed", "Table")])
def test_a_source_that_does_not_repeat_refuses_a_frequency_scale_in_c_and_python(
        custom_fmus, name, kind):
    """A table or a random record has no line frequency: both builds refuse a factor
    (the same sentence), and take 1."""
    from distfmu.presets import retimed
    from distfmu.sources import SourceError
    from tests.nativefmu.test_native import _initialisation_messages

    native_fmu, _ = custom_fmus[name]
    words = f"a {kind} source does not repeat"
    assert any(words in m for m in _initialisation_messages(
        native_fmu, {"preset": "custom", "frequency_scale": 1.05}))
    with pytest.raises(SourceError, match=words):
        retimed(SOURCES[name], 1.05)
    run(native_fmu, outputs=WRENCH, step_size=7e-3, n_steps=2,
        parameters={"frequency_scale": 1.0})
