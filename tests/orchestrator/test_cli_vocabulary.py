"""One command-line vocabulary: the same option means the same thing in every command,
every default is in --help, and an old spelling still works with a one-line note."""

from __future__ import annotations

import argparse

import pytest

from orchestrator.cli import _options, build_parser, main


def commands():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices


def options(sub):
    """The options of a command that take a value and may be left out."""
    for a in sub._actions:
        if (a.option_strings and a.nargs != 0 and not a.required
                and a.help is not argparse.SUPPRESS):
            yield a


def rendered(sub, action) -> str:
    return sub._get_formatter()._get_help_string(action) % {"default": action.default}


def test_every_default_is_in_the_help():
    missing = []
    for name, sub in commands().items():
        for a in options(sub):
            named = a.option_strings[0] in _options.VOCABULARY
            valued = a.default not in (None, [], argparse.SUPPRESS)
            if (named or valued) and "default" not in rendered(sub, a):
                missing.append(f"{name} {a.option_strings[0]}")
    assert not missing, missing


def test_a_value_default_is_shown_as_it_is():
    sub = commands()["analyze"]
    fmin = next(a for a in sub._actions if "--fmin" in a.option_strings)
    assert rendered(sub, fmin).endswith("(default: 0.1)")
    assert "(default: 0.1)" in " ".join(sub.format_help().split())


@pytest.mark.parametrize("option, same", [
    ("--stop", ("type", "metavar", "dest")),
    ("--workers", ("type", "metavar", "dest", "default")),
    ("--out", ("dest", "default")),
    ("--fmu-dir", ("metavar", "dest", "default")),
])
def test_an_option_has_one_meaning_in_every_command(option, same):
    found = {name: next(a for a in sub._actions if option in a.option_strings)
             for name, sub in commands().items()
             if any(option in a.option_strings for a in sub._actions)}
    assert len(found) >= 2
    for attr in same:
        values = {name: getattr(a, attr) for name, a in found.items()
                  if not a.required}
        assert len(set(map(repr, values.values()))) <= 1, (attr, values)


def test_fmu_dir_is_searched_first_everywhere():
    for name, sub in commands().items():
        for a in sub._actions:
            if "--fmu-dir" in a.option_strings:
                assert a.help.startswith("folder searched first for FMUs"), name


def test_out_is_a_folder_but_where_a_command_writes_one_file():
    one_file = ("report", "import-nastran")
    for name, sub in commands().items():
        for a in sub._actions:
            if "--out" in a.option_strings and name not in one_file:
                assert a.metavar == "DIR", name


def test_the_output_folders_default_to_out_and_the_name():
    for name in ("run", "campaign", "reproduce", "design"):
        sub = commands()[name]
        out = next(a for a in sub._actions if "--out" in a.option_strings)
        assert out.default is None and "(default: out/<" in out.help, name


def test_the_old_spelling_of_stop_still_works_with_a_note(capsys):
    args = build_parser().parse_args(["run", "x.toml", "--stop-time", "0.5"])
    assert args.stop == 0.5
    err = capsys.readouterr().err
    assert err == ("jitterfmu: note: --stop-time is an old spelling of --stop, kept for one "
                   "release; use --stop\n")
    assert "--stop-time" not in commands()["run"].format_help()


def test_run_csv_is_an_old_spelling_of_format_csv(capsys):
    """``--csv`` is a file in analyze; in run it was a flag for ``--format csv``."""
    args = build_parser().parse_args(["run", "x.toml", "--csv"])
    assert args.fmt == "csv"
    assert "old spelling of --format csv" in capsys.readouterr().err
    assert "--csv" not in commands()["run"].format_help()


def test_workers_default_to_the_cpus_in_the_help():
    import os

    for name in ("campaign", "reproduce"):
        sub = commands()[name]
        workers = next(a for a in sub._actions if "--workers" in a.option_strings)
        assert f"the number of CPUs, {os.cpu_count() or 1} here" in workers.help


def test_reproduce_truss_frf_ends_with_a_verdict_not_a_json_dump(tmp_path, capsys):
    assert main(["reproduce", "truss-frf", "--quick", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0] == "verdict: reproduced"
    assert "Fig. 4: FRF zero, 6 modes + 2 static Ritz vectors: 5.6 Hz" in out
    assert "{" not in out and "  zero_hz_modal: " in out


def test_unconnected_inputs_are_counted_with_where_to_see_them(tmp_path, capsys, suite_fmus,
                                                               suite_fmu_dir):
    import json
    import tomllib
    from pathlib import Path

    scen = Path(__file__).resolve().parents[2] / "scenarios" / "truss10_closed_loop.toml"
    suite_fmus(*(s["fmu"] for s in tomllib.loads(scen.read_text())["fmus"].values()))
    out = tmp_path / "run"
    assert main(["run", str(scen), "--stop", "0.02", "--out", str(out), "--fmu-dir",
                 str(suite_fmu_dir), "--quiet"]) == 0
    names = json.loads((out / "run.json").read_text())["unconnected_inputs"]
    assert len(names) == 4
    err = [ln for ln in capsys.readouterr().err.splitlines() if "not connected" in ln]
    assert err == [f"jitterfmu: warning: 4 inputs are not connected and keep their start "
                   f"values (e.g. {', '.join(names[:3])}); all 4 names: "
                   f"{out / 'run.json'} (unconnected_inputs)"]


def test_a_few_unconnected_inputs_are_named_in_the_line():
    from orchestrator.cli import unconnected_text

    text = "1 input(s) are not connected and keep their start values: sc.u"
    assert unconnected_text(text) == "1 input is not connected and keeps its start value: sc.u"
    assert unconnected_text("something else") == "something else"


def test_a_campaign_says_its_unconnected_inputs_once_and_lists_them_in_a_file(
        tmp_path, capsys, suite_fmus, suite_fmu_dir):
    import tomllib
    from pathlib import Path

    import tomli_w

    scen = Path(__file__).resolve().parents[2] / "scenarios" / "truss10_closed_loop.toml"
    suite_fmus(*(s["fmu"] for s in tomllib.loads(scen.read_text())["fmus"].values()))
    camp = tmp_path / "c.toml"
    camp.write_text(tomli_w.dumps({
        "campaign": {"name": "wiring", "scenario": str(scen), "stop": 0.1},
        "events": [{"name": "a", "overrides": {"excitation.amp1": 1.0}},
                   {"name": "b", "overrides": {"excitation.amp2": 1.0}}],
        "instruments": [{"name": "tip", "axes": {"pitch": "structure.los_tip_pitch"}}],
        "metrics": [{"kind": "rms"}]}))
    out = tmp_path / "o"
    assert main(["campaign", str(camp), "--out", str(out), "--workers", "0", "--fmu-dir",
                 str(suite_fmu_dir)]) == 0
    listed = (out / "unconnected_inputs.txt").read_text().split()
    assert len(listed) == 4 and "structure.f_tip_x" in listed
    lines = capsys.readouterr().err.splitlines()
    assert lines[0].startswith("jitterfmu: campaign 'wiring': 2 cases")   # the start first
    err = [ln for ln in lines if "not connected" in ln]
    assert err == [f"jitterfmu: warning: 4 inputs are not connected and keep their start "
                   f"values (e.g. {', '.join(listed[:3])}); all 4 names: "
                   f"{out / 'unconnected_inputs.txt'}"]


def test_quiet_means_the_same_wherever_it_is():
    helps = {name: next(a.help for a in sub._actions if "--quiet" in a.option_strings)
             for name, sub in commands().items()
             if any("--quiet" in a.option_strings for a in sub._actions)}
    assert set(helps) >= {"run", "campaign"}
    assert len(set(helps.values())) == 1, helps


def test_import_nastran_says_what_its_unset_options_mean():
    """--shift and the matrix names left out have a meaning; the help says it."""
    text = " ".join(commands()["import-nastran"].format_help().split())
    assert "rigid-body modes (default: 0, a constrained model)" in text
    assert "(default: the one of KGG, KNN, KFF, KAA there, else its one square K*" in text
    assert "(default: the one of MGG, MNN, MFF, MAA there, else its one square M*" in text
