"""``jitterfmu export-fmu`` never overwrites a file it reads, and names a bad argument in
one sentence (the hostile-input round: a scenario replaced by the FMU zip, an inner FMU
replaced by the container, ``--output time``, ``out`` a folder)."""

from __future__ import annotations

import hashlib
import json
import shutil
import zipfile
from pathlib import Path

import pytest

from orchestrator.cli import main

REPO = Path(__file__).resolve().parents[2]
TRUSS = ["truss10_structure", "piezo_p243_40", "piezo_p243_30", "controller_truss10_strain_diag",
         "controller_truss10_strain_long", "excitation"]


@pytest.fixture()
def own(suite_fmus, suite_fmu_dir, tmp_path):
    """A private copy of the truss FMUs and its scenario (a failing test damages no other),
    with the disturbance FMU that the String-parameter tests add."""
    suite_fmus(*TRUSS, "disturbance")
    d = tmp_path / "D"
    d.mkdir()
    for name in TRUSS + ["disturbance"]:
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
    # the start line (an export compiles for seconds), then the one sentence
    assert "Traceback" not in err and len(lines) == 2, err
    assert lines[0].startswith("jitterfmu: export-fmu '") and \
        ": compiling its native FMUs and the master's schedule into '" in lines[0], err
    return lines[1]


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


def _with_string_parameter(tmp_path, value):
    from .test_container import MIXED

    text = MIXED.replace("[[actions]]", '[fmus.dist]\nfmu = "disturbance"\nperiod = 1e-3\n'
                         f"parameters = {{ preset = {json.dumps(value)} }}\n"
                         '[[connections]]\nfrom = "dist.Fx"\nto = "structure.f_tip_x"\n'
                         "[[actions]]")
    (tmp_path / "s.toml").write_text(text)
    return tmp_path / "s.toml"


@pytest.mark.long   # make test-full: compiles two FMUs, 6 s
def test_a_string_parameter_with_a_newline_or_trigraph_compiles_as_written(own, tmp_path):
    """A newline, ``??/`` (a C99 trigraph for a backslash), a quote and a non-ASCII letter
    in a String parameter: the container's sources hold it as octal escapes and compile
    (before: a raw gcc error dump)."""
    import warnings

    from nativefmu.container import export_fmu

    _, d = own
    value = 'a\nb??/c"d\\é'
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fmu = export_fmu(_with_string_parameter(tmp_path, value), tmp_path / "x.fmu",
                         fmu_dir=d, windows=False)
    with zipfile.ZipFile(fmu) as z:
        header = z.read("sources/container_data.h").decode()
    assert r'"a\012b\077\077/c\042d\134\303\251"' in header


def test_a_string_parameter_longer_than_a_c_string_is_one_sentence(own, tmp_path, capsys):
    _, d = own
    s = _with_string_parameter(tmp_path, "x" * 20000)
    err = _refused(capsys, ["export-fmu", str(s), str(tmp_path / "x.fmu"), "--fmu-dir", str(d),
                            "--no-windows"])
    assert "the String 'preset' is 20000 bytes long, more than the 4095" in err
