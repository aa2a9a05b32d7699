"""Long work is never silent: timed lines with the time left when stderr is a log."""

import io
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from orchestrator import progress
from orchestrator.progress import ProgressBar, stage


class Tty(io.StringIO):
    def isatty(self):
        return True


def test_off_a_terminal_a_line_says_what_is_done_and_what_is_left():
    log = io.StringIO()
    bar = ProgressBar(4, "campaign", "case", stream=log, every=0.0)
    bar.update()
    bar.update("failed")
    bar.close()
    lines = log.getvalue().splitlines()
    assert len(lines) == 2
    assert lines[0].startswith("campaign: 1/4 cases, 0:00 elapsed, about 0:00 left")
    assert lines[1].startswith("campaign: 2/4 cases, 1 failed, ")


def test_lines_are_spaced_by_the_interval():
    log = io.StringIO()
    bar = ProgressBar(1.0, "jitterfmu run x.toml", stream=log, every=3600.0)
    for k in range(1, 11):
        bar(k / 10)
    bar.close()
    assert log.getvalue() == ""   # none before the interval has passed


def test_a_fraction_reports_percent():
    log = io.StringIO()
    bar = ProgressBar(1.0, "run", stream=log, every=0.0)
    bar(0.25)
    bar.close()
    assert log.getvalue().startswith("run: 25 %, ")


def test_disabled_is_silent_and_a_terminal_gets_no_lines():
    log = io.StringIO()
    bar = ProgressBar(3, "c", "case", enabled=False, stream=log, every=0.0)
    bar.update()
    assert log.getvalue() == ""
    tty = Tty()
    bar = ProgressBar(3, "c", "case", stream=tty, every=0.0, delay=3600)
    bar.update()
    bar.close()
    assert "cases," not in tty.getvalue()   # the bar, not the log lines


def test_stage_is_one_line():
    log = io.StringIO()
    stage("truss-decay: co-simulating 12 s", stream=log)
    assert log.getvalue() == "jitterfmu: truss-decay: co-simulating 12 s\n"


def test_a_line_comes_while_nothing_finishes():
    """The clock thread writes a line every interval even before the first case ends."""
    log = io.StringIO()
    bar = ProgressBar(3, "campaign", "case", stream=log, every=0.1)
    time.sleep(0.45)
    bar.close()
    lines = log.getvalue().splitlines()
    assert len(lines) >= 2
    assert lines[0].startswith("campaign: 0/3 cases, ")
    assert lines[0].endswith("time left known after the first case")


def test_the_interval_from_the_environment_is_capped_below_30_s(monkeypatch):
    monkeypatch.setenv("JITTERFMU_LOG_EVERY", "100")
    assert progress._every() == progress.LOG_EVERY <= 30.0
    monkeypatch.setenv("JITTERFMU_LOG_EVERY", "0.5")
    assert progress._every() == 0.5
    monkeypatch.setenv("JITTERFMU_LOG_EVERY", "soon")
    assert progress._every() == progress.LOG_EVERY


def test_a_long_campaign_logged_to_a_file_has_no_gap_longer_than_the_interval(tmp_path):
    """Two cases of 4 s each, stderr to a file, lines due every 0.5 s: the file is
    watched while the command runs and no two lines (nor the last line and the end) are
    more than 2.5 s apart (the interval and room for a loaded machine), which only the
    clock thread makes true (a case ends only every 4 s).  The interval is the production one scaled down by the environment."""
    import tomli_w

    from tests.orchestrator.test_campaign import campaign_data

    path = tmp_path / "c.toml"
    path.write_text(tomli_w.dumps(campaign_data(sleep=4.0, n_events=1)))
    err = tmp_path / "stderr.log"
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "JITTERFMU_LOG_EVERY": "0.5"}
    with open(err, "w") as fh:
        proc = subprocess.Popen(
            [sys.executable, "-c", "import sys; from orchestrator.cli import main; "
             "sys.exit(main())", "campaign", str(path), "--out", str(tmp_path / "o"),
             "--workers", "0", "--runner", "tests.orchestrator.test_campaign:synthetic_runner"],
            stdout=subprocess.PIPE, stderr=fh, cwd=root, env=env)
        stamps, seen = [], 0
        while proc.poll() is None:
            n = err.read_text().count("\n")
            stamps += [time.monotonic()] * (n - seen)
            seen = n
            time.sleep(0.02)
        end = time.monotonic()
        out = proc.stdout.read().decode()
    text = err.read_text()
    assert proc.returncode == 0, text
    assert text.startswith("jitterfmu: campaign 'synthetic': 2 cases"), text
    assert "campaign: 0/2 cases" in text and "campaign: 1/2 cases" in text
    gaps = np.diff(stamps + [end])
    assert gaps.max() < 2.5, (gaps, text)
    assert "budget (" in out        # it ends with the numbers the user came for


def test_a_stage_without_a_bar_says_it_is_still_running():
    log = io.StringIO()
    with progress.heartbeat(stream=log, every=0.2):
        stage("truss-decay: co-simulating 12 s", stream=log)
        time.sleep(0.75)
    lines = log.getvalue().splitlines()
    assert lines[0] == "jitterfmu: truss-decay: co-simulating 12 s"
    assert 2 <= len(lines) - 1 <= 4
    assert all(re.fullmatch(r"jitterfmu: truss-decay: co-simulating 12 s: still running, "
                            r"0:0[01] elapsed", ln) for ln in lines[1:]), lines
    time.sleep(0.3)
    assert len(log.getvalue().splitlines()) == len(lines)   # closed: silent


def test_the_heartbeat_keeps_quiet_while_a_bar_speaks():
    log, bars = io.StringIO(), io.StringIO()
    with progress.heartbeat(stream=log, every=0.2):
        stage("campaign 'x': 3 cases", stream=log)
        bar = ProgressBar(3, "campaign", "case", stream=bars, every=0.2)
        time.sleep(0.6)
        bar.close()
    assert log.getvalue() == "jitterfmu: campaign 'x': 3 cases\n"
    assert "campaign: 0/3 cases" in bars.getvalue()


def test_a_bar_speaks_when_the_command_was_silent_the_interval_not_when_it_started():
    """Within a command the silence that counts is the command's: a stage said 1.6 s
    before a bar starts, lines due every 2 s, so the bar's first line comes 2 s after
    the stage (0.4 s into the bar), not 2 s into the bar (3.6 s)."""
    log = io.StringIO()
    with progress.heartbeat(stream=log, every=2.0):
        stage("eos-budget: 24 cases", stream=log)
        time.sleep(1.6)
        bar = ProgressBar(24, "campaign", "case", stream=log, every=2.0)
        time.sleep(1.2)
        lines = log.getvalue().splitlines()
        bar.close()
    assert len(lines) == 2 and lines[1].startswith("campaign: 0/24 cases, "), lines


def test_a_terminal_bar_keeps_its_clock_moving_while_nothing_finishes():
    """On a terminal the bar is redrawn every second: its elapsed time moves although no
    sample has finished (a Monte Carlo used to show 0:10 until its first chunk ended)."""
    tty = Tty()
    bar = ProgressBar(10, "uncertainty", "sample", stream=tty)
    time.sleep(2.3)
    shown = tty.getvalue()
    bar.close()
    assert "0/10 [00:02" in shown, shown
    assert "samples," not in shown            # the bar, not the log lines


def _still_running(log):
    return [ln for ln in log.getvalue().splitlines() if "still running" in ln]


def test_a_stage_run_before_says_its_time_left_from_that_run(tmp_path):
    """A stage has no count: its time left is what it took when it last ran to its end
    (kept in a file), and a stage never run says it does not know."""
    times = tmp_path / "stage_times.json"
    log = io.StringIO()
    with progress.heartbeat(stream=log, every=0.2, times=times):
        stage("analyze x: linearising the closed loop", stream=log)
        time.sleep(0.5)
        stage("analyze x: the margins of every loop", stream=log)
        time.sleep(0.05)
    first = _still_running(log)
    assert first and all(ln.endswith("(time left unknown: not run to its end here before)")
                         for ln in first), first
    kept = json.loads(times.read_text())
    assert 0.45 <= kept["analyze x: linearising the closed loop"] < 2.0
    assert set(kept) == {"analyze x: linearising the closed loop",
                         "analyze x: the margins of every loop"}
    # the next run: the same stage, told its time left from the first one
    kept["analyze x: linearising the closed loop"] = 130.0   # as if it took 2:10
    times.write_text(json.dumps(kept))
    log = io.StringIO()
    with progress.heartbeat(stream=log, every=0.2, times=times):
        stage("analyze x: linearising the closed loop", stream=log)
        time.sleep(0.5)
    lines = _still_running(log)
    assert lines and all(re.fullmatch(
        r"jitterfmu: analyze x: linearising the closed loop: still running, 0:0[01] "
        r"elapsed, about 2:(09|10) left \(2:10 when last run here\)", ln) for ln in lines), lines
    # and past it: says so rather than a negative time
    times.write_text(json.dumps({"s": 0.1}))
    log = io.StringIO()
    with progress.heartbeat(stream=log, every=0.2, times=times):
        stage("s", stream=log)
        time.sleep(0.5)
    assert _still_running(log)[-1].endswith("elapsed, past the 0:00 it took when last run here")


@pytest.mark.parametrize("content", ["not json", "[1, 2]", '{"s": "1; rm -rf /"}',
                                     '{"s": NaN}', '{"s": -4}', '{"s": true}'])
def test_a_stage_times_file_that_is_not_durations_is_ignored_and_replaced(tmp_path, content):
    times = tmp_path / "stage_times.json"
    times.write_text(content)
    log = io.StringIO()
    with progress.heartbeat(stream=log, every=0.2, times=times):
        stage("s", stream=log)
        time.sleep(0.6)
    assert _still_running(log)[0].endswith("(time left unknown: not run to its end here before)")
    kept = json.loads(times.read_text())
    assert list(kept) == ["s"] and isinstance(kept["s"], float)


def test_a_failed_command_keeps_no_stage_times(tmp_path):
    times = tmp_path / "stage_times.json"
    with pytest.raises(RuntimeError):
        with progress.heartbeat(stream=io.StringIO(), every=0.2, times=times):
            stage("s", stream=io.StringIO())
            raise RuntimeError("cut short")
    assert not times.exists()
    with progress.heartbeat(stream=io.StringIO(), every=0.2, times=times) as beat:
        stage("s", stream=io.StringIO())
        beat.keep = False
    assert not times.exists()
