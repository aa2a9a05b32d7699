"""A disturbance source stored as data: round trip, checks, the slave's custom preset."""

import json

import numpy as np
import pytest

from distfmu.custom import CustomSourceError, source_from_json, source_to_json
from distfmu.fmuspec import spec_with_source
from distfmu.slave import DisturbanceSlave
from distfmu.sources import (
    BandLimitedRandom,
    Gated,
    Harmonic,
    SpeedProfile,
    Sum,
    Table,
    WheelImbalance,
)

RNG = np.random.default_rng(11)
TABLE = Table(np.cumsum(RNG.uniform(0.01, 0.05, 30)), RNG.standard_normal((30, 6)), "hold")
RANDOM = BandLimitedRandom(psd_freqs=(0.0, 20.0, 40.0), psd_values=(1e-3, 1e-3, 0.0),
                           seed=4, sample_rate=500.0, n_samples=2**10, kind="torque")
T = np.linspace(-0.5, 3.0, 301)


@pytest.mark.parametrize("source", [
    TABLE, RANDOM, Sum((TABLE, RANDOM, Harmonic(3.0, (0.1, 0.2), phases=(0.5, 1.0)))),
    WheelImbalance((1.0, 2.0), (1e-7, 1e-8), (1e-6, 1e-7), speed=100.0),
])
def test_round_trip_gives_the_same_wrench_bit_for_bit(source):
    back = source_from_json(source_to_json(source))
    assert type(back) is type(source)
    np.testing.assert_array_equal(back.wrench(T), source.wrench(T))


@pytest.mark.parametrize("source,message", [
    (Gated(TABLE), "Gated cannot be stored as data"),
    (WheelImbalance((1.0,), (1e-7,), (1e-6,), speed=SpeedProfile((0.0, 1.0), (0.0, 9.0))),
     "speed profile cannot be stored"),
])
def test_sources_without_a_data_form_are_refused(source, message):
    with pytest.raises(CustomSourceError, match=message):
        source_to_json(source)


def _doc(source: dict) -> bytes:
    return json.dumps({"format": "jitterfmu-disturbance-source 1", "source": source}).encode()


GOOD_TABLE = {"type": "Table", "times": [0.0, 1.0], "values": [[0.0] * 6, [1.0] * 6]}


@pytest.mark.parametrize("content,message", [
    (b"{not json", r"source.json is not valid JSON"),
    (b'{"source": {}}', r"has no 'format'"),
    (_doc({"type": "Shell", "cmd": "rm"}), r"source has type 'Shell'; expected one of"),
    (_doc({**GOOD_TABLE, "extra": 1}), r"\(Table\) has unknown field\(s\) \['extra'\]"),
    (_doc({**GOOD_TABLE, "times": [1.0, 0.0]}),
     r"\(Table\) is invalid: table source: time must be strictly increasing"),
    (_doc({**GOOD_TABLE, "values": [[0.0] * 5, [1.0] * 5]}),
     r"\(Table\) is invalid: table source: values have shape \(2, 5\)"),
    (_doc({"type": "Sum", "sources": [GOOD_TABLE, {"type": "BandLimitedRandom",
                                                   "psd_freqs": [0.0, 600.0],
                                                   "psd_values": [1.0, 1.0]}]}),
     r"source.sources\[1\] \(BandLimitedRandom\) is invalid: .*highest PSD frequency"),
    (_doc({"type": "Sum", "sources": GOOD_TABLE}), r"must have exactly a list 'sources'"),
])
def test_bad_source_data_fail_with_one_sentence(content, message):
    with pytest.raises(CustomSourceError, match=message) as info:
        source_from_json(content)
    assert "\n" not in str(info.value)


def test_slave_runs_its_own_source_and_refuses_custom_without_one(tmp_path):
    spec = spec_with_source(TABLE, "my_table")
    assert spec.init_kwargs == {"default_preset": "custom"}
    (tmp_path / "source.json").write_bytes(spec.resources["source.json"])
    s = DisturbanceSlave(instance_name="d", resources=str(tmp_path))
    s.preset, s.scale = "custom", 2.0
    s.setup_experiment(0.0)
    s.exit_initialization_mode()
    s.do_step(0.0, 0.2)
    np.testing.assert_array_equal(np.asarray(s.wrench), 2.0 * TABLE.wrench(0.2))
    bare = DisturbanceSlave(instance_name="d")
    bare.preset = "custom"
    with pytest.raises(CustomSourceError, match="needs the FMU's own source.json"):
        bare.exit_initialization_mode()
