"""The Monte Carlo's kept samples from elsewhere: a part copied from a run with another
seed or other bounds into this run's folder, or holding NaN, inf, -1e300 or a status no
sample has, used to enter the statistics without a word.  Each is named on stderr and
its samples run again; the run ends with the numbers of an uninterrupted run."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from orchestrator.campaign import LinearRunner, campaign_from_dict, run_campaign
from orchestrator.campaign.mcparts import load_parts, save_part
from orchestrator.campaign.mcresults import LIMIT, UNSTABLE
from orchestrator.campaign.montecarlo import run_uncertainty

from .test_uncertainty import _amp_and_gain, _campaign, _samples, truss_fmus  # noqa: F401

SHAPE = (4, 2, 3, 2, 2)   # samples, configurations, events, pairs, metrics
ME = "a" * 64


def _part(tmp_path, values=None, status=None, identity=ME):
    v = np.full((2,) + SHAPE[1:], 1e-6) if values is None else values
    st = np.zeros((2, SHAPE[1]), np.int64) if status is None else status
    save_part(tmp_path, [0, 1], v, st, identity)
    return tmp_path / "part-0000000-0000001.npz"


def _load(tmp_path):
    values, status = np.full(SHAPE, np.nan), np.zeros(SHAPE[:2], int)
    return load_parts(tmp_path, values, status, ME), values, status


def test_a_part_of_this_run_is_read_back(tmp_path):
    st = np.array([[0, LIMIT], [UNSTABLE, 0]])
    v = np.full((2,) + SHAPE[1:], 2e-6)
    v[0, 1] = np.inf                       # the configuration that reached a limit
    _part(tmp_path, v, st)
    done, values, status = _load(tmp_path)
    assert list(done) == [True, True, False, False]
    assert np.array_equal(values[:2], v) and np.array_equal(status[:2], st)


def _bad(edit):
    v = np.full((2,) + SHAPE[1:], 1e-6)
    st = np.zeros((2, SHAPE[1]), np.int64)
    ident = edit(v, st)
    return v, st, ident or ME


@pytest.mark.parametrize("edit, why", [
    (lambda v, st: v.__setitem__((0, 0, 0, 0, 0), np.nan), r"the value nan where a sample "
     r"of status 0 has a finite metric"),
    (lambda v, st: v.__setitem__((1, 1, 2, 1, 1), np.inf), r"the value inf where"),
    (lambda v, st: v.__setitem__((1, 0, 1, 0, 0), -1e300), r"the value -1e\+300 where"),
    (lambda v, st: st.__setitem__((0, 1), 32), r"status 32 is not one a sample can have"),
    (lambda v, st: st.__setitem__((0, 1), 4), r"status 4 is not one a sample can have"),
    (lambda v, st: st.__setitem__((0, 1), LIMIT), r"the value 1e-06 where a sample of "
     r"status 1"),
    (lambda v, st: "b" * 64, r"another run wrote it"),
])
def test_a_part_with_a_value_or_status_no_sample_has_is_named_and_ignored(
        tmp_path, capsys, edit, why):
    v, st, ident = _bad(edit)
    f = _part(tmp_path, v, st, ident)
    done, values, _ = _load(tmp_path)
    err = capsys.readouterr().err
    assert not done.any() and np.isnan(values).all()
    assert f"ignoring kept samples {str(f)!r}" in err and "they run again" in err
    assert re.search(why, err), err


def test_a_part_without_an_identity_is_named_and_ignored(tmp_path, capsys):
    np.savez(tmp_path / "part-0000000-0000001.npz", samples=np.arange(2),
             values=np.full((2,) + SHAPE[1:], 1e-6), status=np.zeros((2, 2), np.int64))
    done, _, _ = _load(tmp_path)
    assert not done.any()
    assert "does not carry the identity of the run" in capsys.readouterr().err


@pytest.mark.parametrize("other", [{"seed": 7}, {"low": 0.5}])
def test_parts_of_a_run_with_another_seed_or_bounds_are_run_again(tmp_path, truss_fmus,  # noqa: F811
                                                                   capsys, other):
    """Run A (seed 6) and run B (seed 7, or another gain bound); B's parts copied over
    A's in A's folder: A names them, runs their samples again, and its samples equal
    those of A's own first run."""
    mine = _amp_and_gain(8, 6, 0.2, 1.5)
    theirs = _amp_and_gain(8, other.get("seed", 6), other.get("low", 0.2), 1.5)
    results = {}
    for name, unc in (("a", mine), ("b", theirs)):
        camp = campaign_from_dict(_campaign(unc))
        runner = LinearRunner(camp.scenario_dir, fmu_dir=truss_fmus)
        run_campaign(camp, tmp_path / name, runner, progress=False)
        rep = json.loads(run_uncertainty(camp, tmp_path / name, runner,
                                         progress=False).read_text())
        results[name] = (camp, runner, Path(rep["kept_in"]), _samples(tmp_path / name))
    camp, runner, kept, first = results["a"]
    assert results["b"][3] != first           # the other run's numbers differ
    copied = 0
    for f in results["b"][2].glob("part-*.npz"):
        shutil.copy2(f, kept / f.name)
        copied += 1
    assert copied
    capsys.readouterr()
    rep = json.loads(run_uncertainty(camp, tmp_path / "a", runner, progress=False).read_text())
    err = capsys.readouterr().err
    assert err.count("another run wrote it") >= 1
    assert rep["resumed"] < 8 and _samples(tmp_path / "a") == first


@pytest.mark.long   # make test-full: a killed Monte Carlo and its workers, 4 s
@pytest.mark.slow
def test_sigkill_of_a_two_worker_monte_carlo_takes_its_workers_with_it(tmp_path, truss_fmus):  # noqa: F811
    """The run killed (SIGKILL: no handler runs) while its two workers compute: within
    a few seconds no process it started is left, the workers and the resource tracker
    included (before, both workers and the tracker ran on, orphaned)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    import psutil
    import tomli_w

    data = _campaign(_amp_and_gain(3000, 6, 0.2, 1.5))
    path = tmp_path / "c.toml"
    path.write_text(tomli_w.dumps(data))
    out = tmp_path / "out"
    cli = "import sys; from orchestrator.cli import main; sys.exit(main(sys.argv[1:]))"
    proc = subprocess.Popen([sys.executable, "-c", cli, "campaign", str(path), "--out",
                             str(out), "--workers", "2", "--quiet", "--fmu-dir",
                             str(truss_fmus)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env={**os.environ,
                                                            "OPENBLAS_NUM_THREADS": "1"})
    parent = psutil.Process(proc.pid)
    deadline = time.monotonic() + 240
    kids = []
    while time.monotonic() < deadline and proc.poll() is None:
        kids = parent.children(recursive=True)
        if len(kids) >= 3 and list(out.glob("uncertainty_parts/*/part-*.npz")):
            break                      # two workers and the tracker, samples being kept
        time.sleep(0.2)
    assert proc.poll() is None and len(kids) >= 3, "the run ended before its workers ran"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    gone, alive = psutil.wait_procs(kids, timeout=15)
    for p in alive:                    # leave nothing behind whatever the outcome
        p.kill()
    assert not alive, [p.cmdline()[:3] for p in alive]
