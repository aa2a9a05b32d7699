"""Campaign faults that used to give a wrong summary, a silent no-op or a lost stop.

Resume trusting a folder that holds another case's files, campaigns that run nothing or
measure nothing, SIGTERM in an in-process campaign, and a plain file where a case folder
should be (pool workers of a zombie parent: test_campaign.py).
"""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from orchestrator.campaign import CampaignError, MasterRunner, campaign_from_dict, run_campaign
from orchestrator.campaign.cases import load_campaign
from orchestrator.cli import main as cli_main

from .test_campaign import campaign_data, read_sorted, synthetic_runner

HERE = Path(__file__).parent


def _toml(tmp_path, data, name="c.toml") -> Path:
    import tomli_w

    path = tmp_path / name
    path.write_text(tomli_w.dumps(data))
    return path


# ----------------------------------------------------------------------------- resume


@pytest.mark.parametrize("damage", ["copied folder", "copied folder, key edited",
                                    "symlinked folder", "symlinked results"])
def test_resume_reruns_a_case_folder_holding_another_cases_files(tmp_path, damage):
    log = tmp_path / "calls.log"
    camp = campaign_from_dict(campaign_data(log=log))
    out = tmp_path / "out"
    run_campaign(camp, out, synthetic_runner, workers=0, progress=False)
    first = read_sorted(out / "summary.parquet")
    cases = out / "cases"
    # event0 | isolation off and event2 | isolation off: other amplitudes, other jitter
    mine, other = camp.cases[0], camp.cases[4]
    other_files = {p.name: p.read_bytes() for p in (cases / other.key).iterdir()}
    shutil.rmtree(cases / mine.key) if damage != "symlinked results" else None
    if damage.startswith("copied folder"):
        shutil.copytree(cases / other.key, cases / mine.key)
        if damage.endswith("key edited"):   # the key agrees, the definition does not
            st = json.loads((cases / mine.key / "case.json").read_text())
            st["key"] = mine.key
            (cases / mine.key / "case.json").write_text(json.dumps(st))
    elif damage == "symlinked folder":
        (cases / mine.key).symlink_to(cases / other.key, target_is_directory=True)
    else:                                   # the folder's own case.json, a linked file
        (cases / mine.key / "results.parquet").unlink()
        (cases / mine.key / "results.parquet").symlink_to(cases / mine.key / "metrics.parquet")
    res = run_campaign(camp, out, synthetic_runner, workers=0, progress=False)
    assert (res.n_run, res.n_skipped, res.n_failed) == (1, 5, 0)
    assert list(res.rerun) == [mine.label]
    assert "\n" not in res.rerun[mine.label] and mine.key[:12] in res.rerun[mine.label]
    assert len(log.read_text().split()) == 7          # that case, and only it, ran again
    assert read_sorted(out / "summary.parquet") == first
    assert not (cases / mine.key).is_symlink()
    assert json.loads((cases / mine.key / "case.json").read_text())["key"] == mine.key
    # the other case's folder, a symlink's target, is untouched
    assert {p.name: p.read_bytes() for p in (cases / other.key).iterdir()} == other_files


@pytest.mark.parametrize("damage", ["copied folder", "symlinked folder"])
def test_a_lost_case_replaces_another_cases_folder_in_its_place(tmp_path, damage):
    # a pool worker died running a case whose folder held another case's files: the
    # summary must not show that other case's jitter under this case's name
    from orchestrator.campaign.store import record_lost

    camp = campaign_from_dict(campaign_data())
    out = tmp_path / "out"
    run_campaign(camp, out, synthetic_runner, workers=0, progress=False)
    cases = out / "cases"
    mine, other = camp.cases[0], camp.cases[4]
    shutil.rmtree(cases / mine.key)
    if damage == "copied folder":
        shutil.copytree(cases / other.key, cases / mine.key)
    else:
        (cases / mine.key).symlink_to(cases / other.key, target_is_directory=True)
    record_lost(cases, mine, "a worker process died while this case ran")
    st = json.loads((cases / mine.key / "case.json").read_text())
    assert (st["key"], st["status"]) == (mine.key, "failed")
    assert json.loads((cases / other.key / "case.json").read_text())["status"] == "ok"
    from orchestrator.campaign import write_summary
    write_summary(camp, out)
    rows = pq.read_table(out / "summary.parquet").to_pylist()
    assert mine.label not in {r["case"] for r in rows}
    assert other.label in {r["case"] for r in rows}


def test_cli_says_in_one_line_that_a_copied_case_runs_again(tmp_path, capsys):
    path = _toml(tmp_path, campaign_data())
    argv = ["campaign", str(path), "--out", str(tmp_path / "o"), "--workers", "0",
            "--runner", "tests.orchestrator.test_campaign:synthetic_runner", "--quiet"]
    assert cli_main(argv) == 0
    camp = load_campaign(path)
    folders = sorted(p for p in (tmp_path / "o" / "cases").iterdir())
    assert len(folders) == 6
    key = json.loads((folders[0] / "case.json").read_text())["key"]
    victim = next(p for p in folders if p.name != key)
    shutil.rmtree(victim)
    shutil.copytree(folders[0], victim)
    capsys.readouterr()
    assert cli_main(argv) == 0
    out, err = capsys.readouterr()
    assert "6 cases: 1 run, 5 already finished, 0 failed" in out
    lines = [ln for ln in err.splitlines() if "running it again" in ln]
    label = next(c.label for c in camp.cases if c.key == victim.name)
    assert len(lines) == 1 and label in lines[0] and key[:12] in lines[0]


# ----------------------------------------------------------------------------- no-ops


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.update(events=[]), r"\[\[events\]\] is empty"),
    (lambda d: d.update(configurations=[]), r"\[\[configurations\]\] is empty"),
    (lambda d: d["metrics"][0].update(windows=[True]),
     r"metric 1 \(peak_to_peak\) window True is not a positive time"),
    (lambda d: d["metrics"][0].update(windows=0.2),
     r"metric 1 \(peak_to_peak\) windows is 0.2; expected a list"),
    (lambda d: d["metrics"][1].update(windows=[2.0]),
     r"metric 2 \(rms_jitter\) window 2.0 s is longer than the record \(0.9 s"),
    (lambda d: d["campaign"].update(skip=1.0),
     r"\[campaign\] skip is 1.0 s, which leaves no record of the 1.0 s run"),
])
def test_a_campaign_that_would_run_or_measure_nothing_is_refused(tmp_path, edit, message):
    data = campaign_data()
    edit(data)
    path = _toml(tmp_path, data)
    with pytest.raises(CampaignError, match=message) as info:
        load_campaign(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def _fmu_campaign(tmp_path, sweep_parameter, stop=0.1):
    """Integrator FMU cases; the sweep's parameter is the culprit under test."""
    base = {"experiment": {"stop": stop, "output_interval": 0.01},
            "fmus": {"sc": {"fmu": "MtIntegrator", "period": 0.01,
                            "parameters": {"x0": 1e-6}}},
            "record": {"variables": ["sc.x"]}}
    return {"campaign": {"name": "fmu", "scenario": base},
            "events": [{"name": "e", "overrides": {"sc.k": 1.0}}],
            "sweeps": [{"parameter": sweep_parameter, "values": [0.0, 1e-6]}],
            "instruments": [{"name": "A", "axes": {"pitch": "sc.x"}}],
            "metrics": [{"kind": "rms"}]}


def test_an_unknown_sweep_variable_is_refused_before_any_case_runs(tmp_path, fmu_dir):
    path = _toml(tmp_path, _fmu_campaign(tmp_path, "sc.x00"))
    camp = load_campaign(path)
    with pytest.raises(CampaignError, match=r"sweep 1 parameter 'sc.x00': FMU "
                       r"MtIntegrator.fmu has no variable 'x00' \(did you mean 'x0'") as info:
        run_campaign(camp, tmp_path / "out", MasterRunner(tmp_path, fmu_dir=fmu_dir),
                     workers=0, progress=False)
    assert str(path) in str(info.value) and "\n" not in str(info.value)
    assert not (tmp_path / "out").exists()                       # no case ran
    # the right name runs
    ok = load_campaign(_toml(tmp_path, _fmu_campaign(tmp_path, "sc.x0"), "ok.toml"))
    res = run_campaign(ok, tmp_path / "ok", MasterRunner(tmp_path, fmu_dir=fmu_dir),
                       workers=0, progress=False)
    assert (res.n_run, res.n_failed) == (2, 0)


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["events"][0].update(overrides={"sc.steps": 3}),
     (r"event 'e' override 'sc.steps': sc.steps is a discrete output; only parameters "
      r"and inputs can be set")),
    (lambda d: d["sweeps"][0].update(values=[0.0, "1e-6"]),
     r"sweep 1 parameter 'sc.x0': sc.x0 is Real; got str '1e-6'"),
])
def test_an_override_the_fmu_cannot_take_is_refused_before_any_case_runs(tmp_path, fmu_dir,
                                                                         edit, message):
    data = _fmu_campaign(tmp_path, "sc.x0")
    edit(data)
    camp = load_campaign(_toml(tmp_path, data))
    with pytest.raises(CampaignError, match=message):
        run_campaign(camp, tmp_path / "out", MasterRunner(tmp_path, fmu_dir=fmu_dir),
                     workers=0, progress=False)
    assert not (tmp_path / "out").exists()


# ----------------------------------------------------------------------------- signals


_CLI = "import sys; from orchestrator.cli import main; sys.exit(main(sys.argv[1:]))"


def _finished(cases_dir: Path) -> dict:
    out = {}
    if cases_dir.is_dir():
        for d in cases_dir.iterdir():
            if not d.name.startswith(".") and (d / "case.json").is_file():
                out[d.name] = json.loads((d / "case.json").read_text())["status"]
    return out


def threaded_runner(scenario: dict, out_dir):
    """The synthetic runner marked as the linear engine: its cases run in threads."""
    return synthetic_runner(scenario, out_dir)


threaded_runner.engine = "linear"


# the master's and the synthetic runner's two ways (7-10 s each) run in make test-full
@pytest.mark.parametrize("runner, workers", [
    pytest.param("master", 0, marks=pytest.mark.long), ("threads", 0),
    pytest.param("synthetic", 0, marks=pytest.mark.long),
    pytest.param("synthetic", 2, marks=pytest.mark.long)])
def test_sigterm_stops_a_campaign_and_keeps_finished_cases(tmp_path, request, runner,
                                                           workers):
    """Stopped between or during cases: the finished ones are kept and counted exactly
    (with threads, the cases in flight finish and are counted with them)."""
    if runner == "master":   # the master's own signal guard is active inside each case
        data = _fmu_campaign(tmp_path, "sc.x0", stop=200.0)
        data["sweeps"][0]["values"] = [i * 1e-6 for i in range(8)]
        data["campaign"]["scenario"]["fmus"]["sc"]["period"] = 0.001
        data["campaign"]["scenario"]["experiment"]["output_interval"] = 0.001
        extra = ["--fmu-dir", str(request.getfixturevalue("fmu_dir"))]
    else:                    # a runner without one
        data = campaign_data(sleep=0.4, n_events=4)
        where = ("tests.orchestrator.test_campaign_hardening:threaded_runner"
                 if runner == "threads" else "tests.orchestrator.test_campaign:synthetic_runner")
        extra = ["--runner", where]
    path = _toml(tmp_path, data)
    out = tmp_path / "out"
    cmd = [sys.executable, "-c", _CLI, "campaign", str(path), "--out", str(out),
           "--workers", str(workers), "--quiet", *extra]
    proc = subprocess.Popen(cmd, cwd=HERE.parents[1], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while len(_finished(out / "cases")) < 1 and proc.poll() is None \
            and time.monotonic() < deadline:
        time.sleep(0.02)
    time.sleep(0.3)                         # into the next case
    proc.send_signal(signal.SIGTERM)
    try:
        _, stderr = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, stderr = proc.communicate()
        pytest.fail(f"campaign still running 30 s after SIGTERM: {stderr[-500:]}")
    n_cases = len(load_campaign(path).cases)
    done = _finished(out / "cases")
    assert proc.returncode == 128 + signal.SIGTERM, stderr
    assert 1 <= len(done) < n_cases, f"{len(done)} of {n_cases} cases ran: not stopped"
    assert set(done.values()) == {"ok"}     # the interrupted case is not recorded as failed
    lines = [ln for ln in stderr.splitlines() if "SIGTERM" in ln]
    assert len(lines) == 1, stderr
    assert f"kept {len(done)} finished case(s)" in lines[0] and str(out) in lines[0]
    assert "run the same command again" in lines[0]
    assert not list((out / "cases").glob(".tmp-*"))
    if runner != "master":                  # and the same command finishes the rest
        again = subprocess.run(cmd, check=False, cwd=HERE.parents[1], capture_output=True,
                               text=True, timeout=120)
        assert again.returncode == 0, again.stderr
        assert (f"{n_cases} cases: {n_cases - len(done)} run, {len(done)} already finished, "
                "0 failed") in again.stdout


# ----------------------------------------------------------------------------- folders


@pytest.mark.parametrize("where", ["out", "out/cases"])
def test_a_plain_file_where_the_campaign_folder_belongs_is_one_sentence(tmp_path, where):
    camp = campaign_from_dict(campaign_data())
    (tmp_path / "out").mkdir() if where != "out" else None
    (tmp_path / where).write_text("not a folder")
    with pytest.raises(CampaignError, match=f"'{tmp_path / where}' is a file, not a campaign "
                       "folder; move it away or choose another --out"):
        run_campaign(camp, tmp_path / "out", synthetic_runner, workers=0, progress=False)
    assert (tmp_path / where).read_text() == "not a folder"


@pytest.mark.parametrize("workers", [0, 2])
def test_a_plain_file_where_a_case_folder_belongs_fails_that_case_only(tmp_path, workers):
    camp = campaign_from_dict(campaign_data())
    out = tmp_path / "out"
    (out / "cases").mkdir(parents=True)
    blocker = out / "cases" / camp.cases[2].key
    blocker.write_text("not a case")
    res = run_campaign(camp, out, synthetic_runner, workers=workers, progress=False)
    assert (res.n_run, res.n_failed) == (6, 1)
    error = res.failures[camp.cases[2].label]
    assert str(blocker) in error and "is a file, not a case folder" in error
    assert "\n" not in error
    assert blocker.read_text() == "not a case"            # the user's file is kept
    rows = {r["case"]: r for r in pq.read_table(out / "cases.parquet").to_pylist()}
    assert rows[camp.cases[2].label]["status"] == "failed"
    assert rows[camp.cases[2].label]["error"] == error
    assert sum(r["status"] == "ok" for r in rows.values()) == 5


def test_the_campaign_docstring_example_is_a_valid_campaign(tmp_path):
    """The module's example file loads as written (paths relative to campaigns/)."""
    import re
    import textwrap

    import orchestrator.campaign as campaign_pkg
    from orchestrator.campaign import load_campaign

    doc = campaign_pkg.__doc__
    block = doc[doc.index("Campaign file (TOML)"):doc.index("Output folder::")]
    text = textwrap.dedent(block.split("::", 1)[1]).strip("\n")
    text = re.sub(r"\s+#.*$", "", text, flags=re.M)   # the comments explain, TOML allows
    root = Path(__file__).resolve().parents[2] / "campaigns"
    rel = re.search(r'^scenario = "(.+)"$', text, re.M).group(1)
    assert (root / rel).is_file()
    text = text.replace(f'"{rel}"', f'"{(root / rel).resolve().as_posix()}"')
    path = tmp_path / "example.toml"
    path.write_text(text + "\n", encoding="utf-8")
    camp = load_campaign(path)
    assert camp.name == "truss10_quick" and len(camp.cases) == 2


@pytest.mark.parametrize("edit, message", [
    (lambda text: text.replace("skip = 0.0", 'skip = "abc"'),
     r"campaign file '.*c.toml': \[campaign\] skip is 'abc'; expected a time in s"),
    (lambda text: text + '\n[[sweeps]]\nparameter = "ctrl_diag.gain"\nvalues = 5\n',
     r"campaign file '.*c.toml': sweep 1 values is 5; expected a list"),
])
def test_campaign_values_of_the_wrong_type_are_one_sentence(tmp_path, edit, message):
    from orchestrator.campaign import CampaignError, load_campaign

    root = Path(__file__).resolve().parents[2] / "campaigns"
    text = (root / "truss10_quick.toml").read_text(encoding="utf-8")
    text = text.replace('"../scenarios/', f'"{(root.parent / "scenarios").as_posix()}/')
    path = tmp_path / "c.toml"
    path.write_text(edit(text), encoding="utf-8")
    with pytest.raises(CampaignError, match=message) as info:
        load_campaign(path)
    assert "\n" not in str(info.value)


def test_a_broken_base_scenario_or_campaign_file_is_named(tmp_path):
    from orchestrator.campaign import CampaignError, load_campaign

    base = tmp_path / "base.toml"
    base.write_text("[experiment\nstop = 1\n", encoding="utf-8")
    camp = tmp_path / "c.toml"
    camp.write_text('[campaign]\nname = "x"\nscenario = "base.toml"\n', encoding="utf-8")
    with pytest.raises(CampaignError, match=r"base scenario '.*base.toml' is not valid TOML"):
        load_campaign(camp)
    camp.write_bytes(b'[campaign]\nname = "\xff"\n')
    with pytest.raises(CampaignError, match=r"campaign file '.*c.toml' is not text "
                       r"\(not UTF-8\) from byte 19 on line 2"):
        load_campaign(camp)
