"""Long work is never silent: timed lines with the time left when stderr is a log."""

import io

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
    assert log.getvalue() == ""   # none before the interval has passed


def test_a_fraction_reports_percent():
    log = io.StringIO()
    bar = ProgressBar(1.0, "run", stream=log, every=0.0)
    bar(0.25)
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
