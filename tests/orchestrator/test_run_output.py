"""Run output that survives: rows flushed during the run, a lock, an honest run.json."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from orchestrator import OutputError, SimulationError, run_scenario
from orchestrator.run import PARTIAL_DIR
from orchestrator.results import read_table

pytestmark = [pytest.mark.slow,
              pytest.mark.filterwarnings("ignore::orchestrator.cosim.UnconnectedInputWarning")]

ROOT = Path(__file__).resolve().parents[2]
CLI = ("import sys; from orchestrator.cli import main; sys.exit(main(sys.argv[1:]))")


def scenario(stop):
    """An integrator of u = 1: x(t) = t, so every row checks itself."""
    return {
        "experiment": {"stop": stop, "output_interval": 1e-3},
        "fmus": {"i": {"fmu": "MtIntegrator", "period": 1e-3, "parameters": {"u": 1.0}}},
        "record": {"variables": ["i.x"]},
    }


def start_long_run(fmu_dir, tmp_path, out):
    scen = tmp_path / "long.toml"
    scen.write_text(tomli_w.dumps(scenario(stop=300.0)))
    env = dict(os.environ, JITTERFMU_FLUSH_SECONDS="0.2")
    return subprocess.Popen([sys.executable, "-c", CLI, "run", str(scen), "--out", str(out),
                             "--fmu-dir", str(fmu_dir), "--quiet"],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def wait_for_parts(out, n=2, timeout=120.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if len(list((out / PARTIAL_DIR).glob("part-*.parquet"))) >= n:
            return
        time.sleep(0.05)
    raise AssertionError(f"no {n} flushed parts in {out / PARTIAL_DIR} after {timeout} s")


def check_rows(table):
    n = len(table["time"])
    assert n > 0
    np.testing.assert_allclose(table["time"], np.arange(n) / 1000, rtol=0, atol=1e-12)
    np.testing.assert_allclose(table["i.x"], table["time"], rtol=0, atol=1e-9)


def test_killed_run_keeps_its_flushed_rows_and_never_says_ok(fmu_dir, tmp_path):
    out = tmp_path / "o"
    # an earlier successful run in the same folder
    run_scenario(scenario(stop=0.01), out, fmu_dir=fmu_dir)
    assert json.loads((out / "run.json").read_text())["status"] == "ok"
    proc = start_long_run(fmu_dir, tmp_path, out)
    try:
        wait_for_parts(out)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "running" and meta["partial_results"] == PARTIAL_DIR
    table = read_table(out / PARTIAL_DIR)
    assert len(table["time"]) > 11  # more than the earlier run's rows
    check_rows(table)
    # the earlier complete run was moved aside, whole, before the killed one started
    assert json.loads((out / "previous/run.json").read_text())["status"] == "ok"
    assert len(read_table(out / "previous/results.parquet")["time"]) == 11
    # the next run into the folder does not delete the kept rows without being told
    with pytest.raises(OutputError, match=rf"holds {len(table['time']):,} rows of a run that "
                       "did not finish"):
        run_scenario(scenario(stop=0.01), out, fmu_dir=fmu_dir)
    assert len(read_table(out / PARTIAL_DIR)["time"]) == len(table["time"])


def interrupt_long_run(fmu_dir, tmp_path, sig):
    """Start a long run, signal it once rows are flushed; (exit code, stderr, out)."""
    out = tmp_path / "o"
    proc = start_long_run(fmu_dir, tmp_path, out)
    try:
        wait_for_parts(out, n=1)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    return proc.returncode, err, out


def test_sigterm_ends_the_run_with_the_rows_so_far(fmu_dir, tmp_path):
    code, err, out = interrupt_long_run(fmu_dir, tmp_path, signal.SIGTERM)
    assert code == 1, err
    assert "run interrupted by SIGTERM at t = " in err
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "interrupted" and "SIGTERM" in meta["error"]
    table = read_table(out / "results.parquet")
    assert len(table["time"]) == meta["rows"]
    check_rows(table)
    assert not (out / PARTIAL_DIR).exists()


def test_sigint_says_where_the_kept_rows_are(fmu_dir, tmp_path):
    code, err, out = interrupt_long_run(fmu_dir, tmp_path, signal.SIGINT)
    assert code == 130, err
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "interrupted" and meta["rows"] > 0
    assert (f"jitterfmu: interrupted; the {meta['rows']} rows recorded so far are in "
            f"{out / 'results.parquet'}") in err
    check_rows(read_table(out / "results.parquet"))


def test_a_busy_output_folder_is_refused_before_anything_runs(fmu_dir, tmp_path):
    out = tmp_path / "o"
    proc = start_long_run(fmu_dir, tmp_path, out)
    try:
        wait_for_parts(out, n=1)
        with pytest.raises(OutputError, match="is in use by another run or campaign"):
            run_scenario(scenario(stop=0.01), out, fmu_dir=fmu_dir)
    finally:
        proc.kill()
        proc.wait(timeout=60)


def test_an_unwritable_output_folder_is_found_before_the_first_step(fmu_dir, tmp_path,
                                                                     capsys):
    from orchestrator.cli import main

    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    scen = tmp_path / "s.toml"
    scen.write_text(tomli_w.dumps(scenario(stop=0.01)))
    code = main(["run", str(scen), "--out", str(blocker / "o"), "--fmu-dir", str(fmu_dir),
                 "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert "jitterfmu: error: output folder" in err and "is not writable" in err
    with pytest.raises(OutputError, match=r"output folder '.*file/o' is not writable"):
        run_scenario(scenario(stop=0.01), blocker / "o", fmu_dir=fmu_dir)


def test_a_failed_rerun_writes_its_rows_and_keeps_the_earlier_ok_aside(fmu_dir, tmp_path):
    out = tmp_path / "o"
    run_scenario(scenario(stop=0.05), out, fmu_dir=fmu_dir)
    bad = scenario(stop=0.05)
    bad["fmus"]["bad"] = {"fmu": "MtFaulty", "period": 1e-3,
                          "parameters": {"fail_time": 0.005, "mode": 1}}
    with pytest.raises(SimulationError):
        run_scenario(bad, out, fmu_dir=fmu_dir)
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "error"
    assert len(read_table(out / "results.parquet")["time"]) == meta["rows"] == 6
    assert not (out / PARTIAL_DIR).exists()
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == [
        "previous", "results.parquet", "run.json"]
    assert len(read_table(out / "previous/results.parquet")["time"]) == 51
