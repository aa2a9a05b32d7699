"""A process extracts each FMU file once for every loop it linearises (a campaign's
configurations, a sweep's points), and again when the file changes.

Reference: the loop linearised with nothing kept (the same matrices, bit for bit)."""

from __future__ import annotations

import shutil
import warnings

import numpy as np
import pytest

from orchestrator.analysis import blocks as blocks_mod
from orchestrator.analysis import scenario as lin_scenario
from orchestrator.analysis.scenario import linearize

pytestmark = pytest.mark.slow

TRUSS = "scenarios/truss10_closed_loop.toml"


@pytest.fixture(scope="module")
def fmus(suite_fmus, suite_fmu_dir):
    from orchestrator.experiments.truss_decay import FMUS

    suite_fmus(*FMUS)
    return suite_fmu_dir


def _lin(fmu_dir, **overrides):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return linearize(TRUSS, overrides=overrides, fmu_dir=fmu_dir)


def test_a_second_loop_of_the_same_fmus_extracts_nothing_and_a_changed_file_is_extracted(
        fmus, tmp_path, monkeypatch):
    monkeypatch.setattr(lin_scenario, "_EXTRACTED", {})
    monkeypatch.setattr(lin_scenario, "_FOLDER", [])
    calls = []
    real = blocks_mod.extract_resources
    monkeypatch.setattr(blocks_mod, "extract_resources",
                        lambda path, res: calls.append(path.name) or real(path, res))
    first = _lin(fmus)
    n_files = len(calls)
    assert n_files == len(set(calls)) >= 5          # one extraction per FMU file
    second = _lin(fmus, **{"ctrl_diag.gain": 2.0})   # another configuration
    assert len(calls) == n_files
    monkeypatch.setattr(lin_scenario, "_EXTRACTED", {})   # nothing kept: the reference
    fresh = _lin(fmus, **{"ctrl_diag.gain": 2.0})
    for name, b in second.blocks.items():
        for m in ("A", "B", "C", "D"):
            np.testing.assert_array_equal(getattr(b, m), getattr(fresh.blocks[name], m))
    assert not np.array_equal(first.lifted(), second.lifted())   # the gain did change it
    # a copy of the folder whose structure FMU differs in content: extracted again
    other = tmp_path / "fmus"
    shutil.copytree(fmus, other, ignore=shutil.ignore_patterns("*.lock"))
    calls.clear()
    _lin(other)
    assert len(calls) == n_files                    # other paths: extracted
    calls.clear()
    py = next(p for p in (other / "python").glob("truss10_structure*.fmu"))
    py.write_bytes(py.read_bytes() + b"\0")         # same path, new content (zip still reads)
    _lin(other)
    assert calls == [py.name]


def test_loops_linearised_in_threads_at_once_are_the_loop(fmus, monkeypatch):
    """Four threads linearising at once (a Dask worker's threads) share the extractions
    without clashing: each loop equals the one linearised alone."""
    from concurrent.futures import ThreadPoolExecutor

    monkeypatch.setattr(lin_scenario, "_EXTRACTED", {})
    monkeypatch.setattr(lin_scenario, "_FOLDER", [])
    gains = [0.5, 1.0, 1.5, 2.0]
    with ThreadPoolExecutor(4) as pool:
        loops = list(pool.map(lambda g: _lin(fmus, **{"ctrl_diag.gain": g}), gains))
    for g, lin in zip(gains, loops):
        np.testing.assert_array_equal(lin.lifted(), _lin(fmus, **{"ctrl_diag.gain": g}).lifted())


def test_a_second_loop_shares_the_blocks_of_the_instances_it_does_not_change(
        fmus, monkeypatch):
    """A campaign's second configuration builds only the blocks whose FMU, parameters
    or periods differ (the structure's discretisation is the costly one); the others
    are the first loop's, and they equal blocks built with nothing kept."""
    monkeypatch.setattr(lin_scenario, "_EXTRACTED", {})
    monkeypatch.setattr(lin_scenario, "_FOLDER", [])
    first = _lin(fmus)
    second = _lin(fmus, **{"ctrl_diag.gain": 2.0})
    sources = set(first.sources)
    for name, b in second.blocks.items():
        if name == "ctrl_diag" or name in sources:
            assert b is not first.blocks[name], name
        else:
            assert b is first.blocks[name], name
    monkeypatch.setattr(lin_scenario, "_EXTRACTED", {})   # nothing kept: the reference
    fresh = _lin(fmus, **{"ctrl_diag.gain": 2.0})
    for name, b in second.blocks.items():
        for m in ("A", "B", "C", "D"):
            np.testing.assert_array_equal(getattr(b, m), getattr(fresh.blocks[name], m))
        assert b.limits == fresh.blocks[name].limits
    np.testing.assert_array_equal(second.lifted(), fresh.lifted())


def test_a_block_built_under_another_blas_thread_count_is_not_shared(fmus, monkeypatch):
    """The structure's exponential moves in its last bits with the BLAS thread count, and
    a Monte Carlo sample's blocks are compared with the nominal ones bit for bit: a loop
    linearised in a worker thread with one BLAS thread (a linear campaign's case) and one
    linearised in the calling thread share their blocks only when the two counts are the
    same."""
    from concurrent.futures import ThreadPoolExecutor

    from orchestrator.analysis._threads import (blas_thread_counts, blas_threads_kept,
                                                one_blas_thread)

    monkeypatch.setattr(lin_scenario, "_EXTRACTED", {})
    monkeypatch.setattr(lin_scenario, "_FOLDER", [])

    def in_worker():
        one_blas_thread()
        return _lin(fmus), blas_thread_counts()

    with blas_threads_kept(), ThreadPoolExecutor(1) as pool:   # the process's count back
        worker, counts = pool.submit(in_worker).result()
    here = _lin(fmus)
    name = next(n for n, b in here.blocks.items() if b.kind == "structure")
    assert counts == [1] * len(counts)
    shared = here.blocks[name] is worker.blocks[name]
    assert shared == (blas_thread_counts() == counts)
    # either way, the same matrices to the exponential's round-off
    np.testing.assert_allclose(here.blocks[name].A, worker.blocks[name].A, rtol=0,
                               atol=1e-11 * np.abs(here.blocks[name].A).max())
