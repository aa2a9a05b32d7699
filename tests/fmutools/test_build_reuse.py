"""``jitterfmu build`` keeps the FMUs it already built from the same sources.

The key is the content of the sources (``fmutools.registry.sources_hash``, stamped per
folder in ``.sources``): an FMU whose sources changed since, or that is missing, is built
again; ``--force`` rebuilds all.
"""

import json

import pytest

from orchestrator.cli import main


def _bytes(folder):
    return {p.relative_to(folder).as_posix(): p.stat().st_mtime_ns
            for p in folder.rglob("*.fmu")}


@pytest.mark.long   # make test-full: builds the suite's FMUs, 11 s
@pytest.mark.slow
def test_build_twice_keeps_what_it_built(tmp_path, capsys):
    args = ["build", "--model", "excitation", "--model", "acs", "--out", str(tmp_path)]
    assert main(args) == 0
    first = _bytes(tmp_path)
    assert set(first) == {"excitation.fmu", "acs.fmu", "python/excitation.fmu",
                          "python/acs.fmu"}
    capsys.readouterr()
    assert main(args) == 0                       # nothing to do: every FMU kept
    out = capsys.readouterr().out
    assert "kept 4 FMU(s) already built from these sources" in out and "[1/" not in out
    assert _bytes(tmp_path) == first
    # the sources of acs changed (its stamp no longer matches), and excitation is missing
    for folder in (tmp_path, tmp_path / "python"):
        stamps = json.loads((folder / ".sources").read_text())
        stamps["acs"] = "0" * 64
        (folder / ".sources").write_text(json.dumps(stamps))
    (tmp_path / "excitation.fmu").unlink()
    assert main(args) == 0
    out = capsys.readouterr().out
    now = _bytes(tmp_path)
    assert now["python/excitation.fmu"] == first["python/excitation.fmu"]   # kept
    assert now["acs.fmu"] != first["acs.fmu"] and now["python/acs.fmu"] != first["python/acs.fmu"]
    assert (tmp_path / "excitation.fmu").is_file() and "acs" in out
    before = _bytes(tmp_path)
    assert main(args + ["--force"]) == 0          # --force rebuilds every one
    after = _bytes(tmp_path)
    assert all(after[k] != before[k] for k in before)


@pytest.mark.slow
def test_fmus_built_for_this_machine_only_are_kept_and_said(tmp_path, suite_fmus, capsys):
    """FMUs ensure_fmus built (jitterfmu reproduce, make demo: linux64 only) are current:
    build keeps them and, with a cross compiler, says they lack win64 binaries."""
    from fmutools.ensure import ensure_fmus
    from nativefmu.build import mingw_compiler

    ensure_fmus(["excitation"], tmp_path)
    first = _bytes(tmp_path)
    capsys.readouterr()
    assert main(["build", "--model", "excitation", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "kept 2 FMU(s)" in out and _bytes(tmp_path) == first
    assert ("have no win64 binary" in out) == (mingw_compiler() is not None)
