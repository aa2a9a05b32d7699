"""The process's BLAS thread count survives the analyses that run in threads.

OpenBLAS's "local" thread count, which each worker thread of the linear engine sets to
one, is seen by the process's other threads too.  Left so, every later product of the
process ran on one thread, and the exponential of the stiff Ritz block that an FMU build
packs moved in its last bits (2.7e-12 on the EOS model): the FMI 3.0 FMUs built after a
linear campaign differed from the FMI 2.0 ones built before it, by 1.9e-15 of the line
of sight, and the bit-for-bit test between them failed whenever a test file with a linear
campaign ran first in its worker.
"""

from __future__ import annotations

import threading

import numpy as np

from orchestrator.analysis._threads import (blas_thread_counts, blas_threads_kept,
                                            map_threads, one_blas_thread)
from structfmu.discrete import block_zoh


def _stiff_block():
    """A stiff second-order block (kHz modes, light damping) like a Ritz block."""
    rng = np.random.default_rng(0)
    n = 69
    K = rng.standard_normal((n, n))
    return K @ K.T * 1e6, np.eye(n) * 10.0


def test_a_worker_threads_one_blas_thread_leaks_and_is_given_back():
    """The leak itself (on a machine whose OpenBLAS runs more than one thread: with one,
    there is nothing to leak), and its cure: a block of blas_threads_kept ends with the
    counts it began with."""
    before = blas_thread_counts()
    with blas_threads_kept():
        t = threading.Thread(target=one_blas_thread)
        t.start()
        t.join()
        during = blas_thread_counts()
    assert during == [1] * len(before)            # the worker's count reached this thread
    assert blas_thread_counts() == before


def test_threaded_analyses_leave_the_process_its_bits(tmp_path, suite_fmus, suite_fmu_dir):
    """The exponential an FMU build packs is the same bits before and after map_threads
    and after a campaign on the linear engine (its cases run in threads)."""
    from orchestrator.campaign import LinearRunner, campaign_from_dict, run_campaign
    from tests.orchestrator.test_uncertainty import _campaign

    K, D = _stiff_block()
    before, counts = block_zoh(K, D, 1e-3), blas_thread_counts()
    map_threads(lambda x: x @ x, [np.eye(200)] * 4, workers=2)
    assert blas_thread_counts() == counts
    from tests.orchestrator.test_truss10_campaign import FMUS
    suite_fmus(*FMUS)
    data = _campaign({"samples": 1, "parameters": [{"kind": "phase",
                                                    "instances": ["excitation"]}]})
    data["events"].append({"name": "longeron", "overrides": {"excitation.amp2": 10.0}})
    camp = campaign_from_dict(data)
    run_campaign(camp, tmp_path, LinearRunner(camp.scenario_dir, fmu_dir=suite_fmu_dir),
                 workers=2, progress=False)
    assert blas_thread_counts() == counts
    after = block_zoh(K, D, 1e-3)
    assert all(np.array_equal(a, b) for a, b in zip(before, after))


def test_thread_counts_are_read_without_setting_them(monkeypatch):
    """The count is read with OpenBLAS's query where every loaded library has one (no
    thread computes on a count set for a moment); where one has none, it is set and put
    back, as before.  Fake libraries record the calls."""
    from orchestrator.analysis import _threads

    calls = []
    state = {"a": 3, "b": 5}

    def setter(name):
        def fn(n):
            calls.append(("set", name, n))
            old, state[name] = state[name], n
            return old
        return fn

    def getter(name):
        return lambda: calls.append(("get", name)) or state[name]

    libs = ((setter("a"), getter("a")), (setter("b"), getter("b")))
    monkeypatch.setattr(_threads, "_openblas", lambda: libs)
    assert blas_thread_counts() == [3, 5]
    assert [c[0] for c in calls] == ["get", "get"]
    calls.clear()
    monkeypatch.setattr(_threads, "_openblas", lambda: (libs[0], (libs[1][0], None)))
    assert blas_thread_counts() == [3, 5]
    assert [c[0] for c in calls] == ["set", "set", "set", "set"] and state == {"a": 3, "b": 5}
    # and on the loaded libraries both ways agree
    monkeypatch.undo()
    read, loaded = blas_thread_counts(), _threads._openblas()
    monkeypatch.setattr(_threads, "_openblas", lambda: tuple((s, None) for s, _ in loaded))
    assert blas_thread_counts() == read
