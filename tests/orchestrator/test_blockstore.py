"""The store of built blocks: a loop linearised in another process reads its structure,
piezo and controller blocks from disk, bit for bit the blocks built from the FMUs.

References: the same loop linearised with the store off (every block built from its FMU),
compared field by field and as the lifted closed-loop map; a damaged or foreign entry is
built again, never read."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from orchestrator.analysis import blockstore
from orchestrator.analysis._threads import blas_threads_kept, one_blas_thread
from orchestrator.analysis.blocks import _disk_key
from orchestrator.analysis import scenario as lin_scenario
from orchestrator.analysis.scenario import linearize

pytestmark = pytest.mark.slow

TRUSS = "scenarios/truss10_closed_loop.toml"
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def fmus(suite_fmus, suite_fmu_dir):
    from orchestrator.experiments.truss_decay import FMUS

    suite_fmus(*FMUS)
    return suite_fmu_dir


@pytest.fixture
def store(tmp_path, monkeypatch):
    """The store on, in a cache of this test; nothing kept in the process."""
    monkeypatch.setenv("JITTERFMU_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("JITTERFMU_BLOCK_CACHE", "on")
    monkeypatch.setattr(blockstore, "STATS", {k: 0 for k in blockstore.STATS})
    fresh(monkeypatch)
    return tmp_path / "cache" / "blocks"


def fresh(monkeypatch):
    """As a new process: no extraction or block kept."""
    monkeypatch.setattr(lin_scenario, "_EXTRACTED", {})
    monkeypatch.setattr(lin_scenario, "_FOLDER", [])


def _lin(fmu_dir, **overrides):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return linearize(TRUSS, overrides=overrides, fmu_dir=fmu_dir)


def _equal(a, b, what):
    """Two values of a block field: arrays bit for bit, tuples element by element."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        assert isinstance(a, np.ndarray) and isinstance(b, np.ndarray), what
        assert a.dtype == b.dtype and a.shape == b.shape, what
        np.testing.assert_array_equal(a, b, err_msg=what)
    elif isinstance(a, tuple) or isinstance(b, tuple):
        assert isinstance(a, tuple) and isinstance(b, tuple) and len(a) == len(b), what
        for i, (x, y) in enumerate(zip(a, b)):
            _equal(x, y, f"{what}[{i}]")
    else:
        assert a == b, what


FIELDS = ("name", "kind", "period", "A", "B", "C", "D", "inputs", "outputs", "feedthrough",
          "active", "continuous", "limits", "unmodelled", "flags", "t_on", "inner")
MODEL = ("omega", "modal_damping", "B_e", "C_e", "K_oo", "D_oo", "B_o", "C_o", "name",
         "input_names", "output_names", "output_kinds", "meta")


def _same_blocks(kept, built):
    assert kept.keys() == built.keys()
    for name, b in built.items():
        k = kept[name]
        for f in FIELDS:
            _equal(getattr(k, f), getattr(b, f), f"{name}.{f}")
        if b.kind == "structure":
            for f in MODEL:
                _equal(getattr(k.model, f), getattr(b.model, f), f"{name}.model.{f}")
            assert k.model.accel_lowpass == b.model.accel_lowpass


def test_a_loop_of_another_process_reads_its_blocks_and_they_are_the_built_ones(
        fmus, store, monkeypatch):
    first = _lin(fmus)
    kinds = {b.kind for b in first.blocks.values()}
    assert {"structure", "piezo", "controller"} <= kinds
    kept = [b for b in first.blocks.values() if b.kind in blockstore.KEPT]
    assert blockstore.STATS["written"] == len(kept)
    assert len(list(store.glob("*.npz"))) == len(kept)
    fresh(monkeypatch)
    second = _lin(fmus)
    assert blockstore.STATS["hit"] == len(kept)           # every kept kind read, none built
    monkeypatch.setenv("JITTERFMU_BLOCK_CACHE", "off")    # the reference: built from FMUs
    fresh(monkeypatch)
    built = _lin(fmus)
    _same_blocks(second.blocks, built.blocks)
    np.testing.assert_array_equal(second.lifted(), built.lifted())
    # a read controller's gain factor builds its live block: the same loop as a built one
    ctrl = next(n for n, b in built.blocks.items() if b.kind == "controller" and b.active)
    np.testing.assert_array_equal(second.with_gain(ctrl, 0.5).lifted(),
                                  built.with_gain(ctrl, 0.5).lifted())
    assert not np.array_equal(second.with_gain(ctrl, 0.5).lifted(), built.lifted())


def test_a_new_process_reads_the_store_and_closes_the_same_loop(fmus, store, tmp_path):
    # both processes on one BLAS thread (the count is a part of the key)
    with blas_threads_kept():
        one_blas_thread()
        first = _lin(fmus)
    code = ("import json, sys, warnings, numpy as np\n"
            "from orchestrator.analysis import blockstore, linearize\n"
            "from orchestrator.analysis._threads import one_blas_thread\n"
            "warnings.simplefilter('ignore')\n"
            "one_blas_thread()\n"
            f"lin = linearize({TRUSS!r}, fmu_dir=sys.argv[1])\n"
            "np.save(sys.argv[2], lin.lifted())\n"
            "print(json.dumps(blockstore.STATS))\n")
    out = subprocess.run([sys.executable, "-c", code, str(fmus), str(tmp_path / "l.npy")],
                         cwd=ROOT, env=dict(os.environ), capture_output=True, text=True,
                         check=True)
    stats = json.loads(out.stdout.strip().splitlines()[-1])
    assert stats["hit"] == sum(b.kind in blockstore.KEPT for b in first.blocks.values()), stats
    assert stats["written"] == 0
    np.testing.assert_array_equal(np.load(tmp_path / "l.npy"), first.lifted())


def _damage(path: Path, how: str):
    if how == "truncated":
        path.write_bytes(path.read_bytes()[:200])
    elif how == "an object array":   # a pickle inside: never loaded
        np.savez(path, header=np.array([{"format": "jitterfmu-block"}], dtype=object))
    elif how == "altered arrays":    # its header's digest no longer matches
        with np.load(path, allow_pickle=False) as f:
            arrays = {k: f[k] for k in f.files}
        arrays["A"] = arrays["A"] * 2.0
        np.savez(path, **arrays)
    elif how == "writable by others":
        os.chmod(path, 0o666)
    else:
        raise AssertionError(how)


@pytest.mark.parametrize("how", ["truncated", "an object array", "altered arrays",
                                 "writable by others"])
def test_a_damaged_or_foreign_entry_is_built_again_not_read(fmus, store, monkeypatch, how):
    reference = _lin(fmus)
    struct = next(n for n, b in reference.blocks.items() if b.kind == "structure")
    plan = reference.plan
    inst = next(i for i in plan.scenario.instances if i.name == struct)
    entry = store / f"{_disk_key(plan, inst)}.npz"
    assert entry.is_file()
    _damage(entry, how)
    fresh(monkeypatch)
    monkeypatch.setattr(blockstore, "STATS", {k: 0 for k in blockstore.STATS})
    again = _lin(fmus)
    assert blockstore.STATS["refused"] == 1
    _same_blocks(again.blocks, reference.blocks)
    np.testing.assert_array_equal(again.lifted(), reference.lifted())
    assert blockstore.STATS["written"] == 1     # written again: the next process reads it
    assert blockstore.STATS["hit"] == sum(b.kind in blockstore.KEPT
                                          for b in reference.blocks.values()) - 1
    fresh(monkeypatch)
    _lin(fmus)
    assert blockstore.STATS["refused"] == 1 and blockstore.STATS["written"] == 1


def test_an_entry_is_another_when_a_parameter_or_the_code_changes(fmus, store, monkeypatch):
    _lin(fmus)
    n = len(list(store.glob("*.npz")))
    fresh(monkeypatch)
    _lin(fmus, **{"ctrl_diag.gain": 2.0})     # one controller's parameter: one new entry
    assert len(list(store.glob("*.npz"))) == n + 1
    monkeypatch.setattr(blockstore, "code_digest", lambda: "other code")
    monkeypatch.setattr(blockstore, "STATS", {k: 0 for k in blockstore.STATS})
    fresh(monkeypatch)
    _lin(fmus)
    assert blockstore.STATS["hit"] == 0 and blockstore.STATS["written"] == n


def test_the_store_off_reads_and_writes_nothing(fmus, store, monkeypatch):
    monkeypatch.setenv("JITTERFMU_BLOCK_CACHE", "off")
    _lin(fmus)
    assert not store.exists() or not list(store.glob("*.npz"))
    assert blockstore.STATS == {"hit": 0, "miss": 0, "written": 0, "refused": 0}


def test_the_least_recently_used_entries_go_beyond_the_stores_bounds(fmus, store,
                                                                      monkeypatch):
    _lin(fmus)
    entries = sorted(store.glob("*.npz"))
    n = len(entries)

    def age():   # distinct ages, the first entry the oldest
        for i, p in enumerate(entries):
            os.utime(p, (1e9 + i, 1e9 + i))
    age()
    fresh(monkeypatch)
    _lin(fmus)                             # every entry read: each touched
    assert min(p.stat().st_mtime for p in entries) > 1e9 + n
    age()
    monkeypatch.setattr(blockstore, "_MAX_ENTRIES", n - 2)
    blockstore._trim(store)                # by count: the two oldest go
    assert set(store.glob("*.npz")) == set(entries[2:])
    age_left = entries[2:]
    size = sum(p.stat().st_size for p in age_left[1:])
    monkeypatch.setattr(blockstore, "_MAX_ENTRIES", 512)
    monkeypatch.setattr(blockstore, "_MAX_BYTES", size)
    blockstore._trim(store)                # by bytes: the newest that fit stay
    assert set(store.glob("*.npz")) == set(age_left[1:])
