"""A linear campaign's threads build its configurations' loops at once, each loop once.

The runner's lock guards its caches only: a thread closing one configuration's loop does
not hold back a thread closing another (a barrier both builds must reach proves they
overlap), and threads asking for a loop another is building wait for that build
(one ``prepare`` per loop, one object for all).  The threads take one case of every
configuration first, then the rest configuration by configuration."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace

import numpy as np
import pytest

from orchestrator.analysis.fast import FastResponse
from orchestrator.campaign import LinearRunner
from orchestrator.campaign.engine import _loops_first
from orchestrator.scenario import load_scenario

TRUSS = "scenarios/truss10_closed_loop.toml"


@pytest.fixture(scope="module")
def truss(suite_fmus, suite_fmu_dir):
    from orchestrator.experiments.truss_decay import FMUS

    suite_fmus(*FMUS)
    data = load_scenario(TRUSS).to_dict()
    return data, suite_fmu_dir


def _with_gain(data: dict, gain: float) -> dict:
    out = {**data, "fmus": {**data["fmus"]}}
    ctrl = dict(out["fmus"]["ctrl_diag"])
    ctrl["parameters"] = {**ctrl.get("parameters", {}), "gain": gain}
    out["fmus"]["ctrl_diag"] = ctrl
    return out


def _counting_prepare(monkeypatch, barrier=None):
    calls = []
    real = FastResponse.prepare

    def prepare(self, channels=None):
        calls.append(threading.current_thread().name)
        if barrier is not None:
            barrier.wait()   # every build must be inside prepare at once to pass
        return real(self, channels)

    monkeypatch.setattr(FastResponse, "prepare", prepare)
    return calls


def test_two_configurations_build_at_once(truss, monkeypatch):
    data, fmu_dir = truss
    barrier = threading.Barrier(2, timeout=60)
    calls = _counting_prepare(monkeypatch, barrier)
    runner = LinearRunner("scenarios", fmu_dir=fmu_dir)
    configs = [_with_gain(data, 0.5), _with_gain(data, 1.5)]
    with ThreadPoolExecutor(2) as pool:
        loops = list(pool.map(runner.compiled, configs))   # a serial build breaks the barrier
    assert len(calls) == 2 and not barrier.broken
    assert loops[0] is not loops[1]
    assert not np.array_equal(loops[0].lin.lifted(), loops[1].lin.lifted())


def test_threads_asking_for_one_loop_build_it_once(truss, monkeypatch):
    data, fmu_dir = truss
    calls = _counting_prepare(monkeypatch)
    runner = LinearRunner("scenarios", fmu_dir=fmu_dir)
    # the same configuration, its source's parameters apart (a campaign's events)
    cases = []
    for amp in (1.0, 2.0, 3.0, 4.0):
        case = {**data, "fmus": {**data["fmus"]}}
        src = dict(case["fmus"]["excitation"])
        src["parameters"] = {**src.get("parameters", {}), "amp1": amp}
        case["fmus"]["excitation"] = src
        cases.append(case)
    with ThreadPoolExecutor(4) as pool:
        loops = list(pool.map(runner.compiled, cases))
    assert len(calls) == 1
    assert all(fr is loops[0] for fr in loops)
    assert runner.compiled(cases[0]) is loops[0] and len(calls) == 1


def test_the_threads_take_one_case_of_every_configuration_first():
    cases = [SimpleNamespace(label=f"{ev} | {cf}", configuration=cf)
             for ev in ("a", "b", "c") for cf in ("off", "on", "half")]
    order = [c.label for c in _loops_first(cases)]
    assert order == ["a | off", "a | on", "a | half",
                     "b | off", "c | off", "b | on", "c | on", "b | half", "c | half"]
    assert sorted(order) == sorted(c.label for c in cases)
