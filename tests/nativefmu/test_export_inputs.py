"""``jitterfmu export-fmu`` never overwrites a file it reads, and names a bad argument in
one sentence (the hostile-input round: a scenario replaced by the FMU zip, an inner FMU
replaced by the container, ``--output time``, ``out`` a folder)."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import pytest

from orchestrator.cli import main

REPO = Path(__file__).resolve().parents[2]
TRUSS = ["truss10_structure", "piezo_p243_40", "piezo_p243_30", "controller_truss10_strain_diag",
         "controller_truss10_strain_long", "excitation"]


@pytest.fixture()
def own(suite_fmus, suite_fmu_dir, tmp_path):
    """A private copy of the truss FMUs and its scenario (a failing test damages no other)."""
    suite_fmus(*TRUSS)
    d = tmp_path / "D"
    d.mkdir()
    for name in TRUSS:
        shutil.copy2(suite_fmu_dir / f"{name}.fmu", d / f"{name}.fmu")
    s = tmp_path / "s.toml"
    shutil.copy2(REPO / "scenarios" / "truss10_closed_loop.toml", s)
    return s, d


def _digest(p):
    return hashlib.sha256(Path(p).read_bytes()).hexdigest()


def _refused(capsys, argv):
    code = main(argv)
    err = capsys.readouterr().err
    assert code != 0
    lines = [x for x in err.splitlines() if "--debug" not in x]
    assert "Traceback" not in err and len(lines) == 1, err
    return lines[0]


def test_export_onto_its_own_scenario_is_refused_and_the_scenario_kept(own, capsys):
    s, d = own
    before = _digest(s)
    err = _refused(capsys, ["export-fmu", str(s), str(s), "--fmu-dir", str(d),
                            "--no-windows"])
    assert "is a file the export reads" in err and "s.toml" in err
    assert _digest(s) == before


def test_export_onto_an_inner_fmu_is_refused_and_a_run_still_works(own, capsys):
    s, d = own
    inner = d / "truss10_structure.fmu"
    before = _digest(inner)
    err = _refused(capsys, ["export-fmu", str(s), str(inner), "--fmu-dir", str(d),
                            "--no-windows"])
    assert "truss10_structure.fmu is a file the export reads" in err
    assert _digest(inner) == before


def test_output_without_a_dot_and_a_folder_as_out_are_one_sentence(own, capsys, tmp_path):
    s, d = own
    err = _refused(capsys, ["export-fmu", str(s), str(tmp_path / "x.fmu"), "--output", "time",
                            "--fmu-dir", str(d), "--no-windows"])
    assert "--output 'time' is not INST.VAR" in err
    folder = tmp_path / "out.fmu"
    folder.mkdir()
    err = _refused(capsys, ["export-fmu", str(s), str(folder), "--fmu-dir", str(d),
                            "--no-windows"])
    assert "is a folder" in err
