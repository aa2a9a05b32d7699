"""ensure_fmus: native FMUs in the folder, their Python twins in python/, rebuilt only
when missing or built from other sources."""

import json
import zipfile

import pytest

from fmutools.ensure import ensure_fmus

pytestmark = pytest.mark.slow


def is_native(path) -> bool:
    with zipfile.ZipFile(path) as z:
        names = z.namelist()
    return any(n.startswith("sources/") for n in names) and not any(
        n.startswith("resources/") and n.endswith(".py") for n in names)


def test_native_by_default_python_twin_beside_and_no_needless_rebuild(tmp_path):
    got = ensure_fmus(["excitation"], tmp_path)
    native, python = got["excitation"], tmp_path / "python" / "excitation.fmu"
    assert native == tmp_path / "excitation.fmu" and native.is_file() and python.is_file()
    assert is_native(native) and not is_native(python)
    stamp = {p: p.stat().st_mtime_ns for p in (native, python)}
    assert ensure_fmus(["excitation"], tmp_path)["excitation"] == native
    assert {p: p.stat().st_mtime_ns for p in (native, python)} == stamp   # not rebuilt
    # sources changed since the build (the stamp says so): both are rebuilt
    for folder in (tmp_path, tmp_path / "python"):
        (folder / ".sources").write_text(json.dumps({"excitation": "other sources"}))
    ensure_fmus(["excitation"], tmp_path)
    assert all(p.stat().st_mtime_ns != t for p, t in stamp.items())


def test_python_kind_builds_only_the_python_twins(tmp_path):
    got = ensure_fmus(["excitation"], tmp_path, kind="python")
    assert got["excitation"] == tmp_path / "python" / "excitation.fmu"
    assert not (tmp_path / "excitation.fmu").exists()


def test_bad_names_and_kinds_are_one_sentence(tmp_path):
    with pytest.raises(KeyError, match=r"no package provides the models \['nosuch_fmu'\]; "
                                       r"known: .*'excitation'"):
        ensure_fmus(["nosuch_fmu"], tmp_path)
    with pytest.raises(ValueError, match="FMU kind 'c' is unknown"):
        ensure_fmus(["excitation"], tmp_path, kind="c")


def test_two_processes_ensuring_one_folder_build_each_fmu_once(tmp_path):
    import subprocess
    import sys

    code = ("import sys; from fmutools.ensure import ensure_fmus; "
            "ensure_fmus(['excitation'], sys.argv[1], progress=print)")
    procs = [subprocess.Popen([sys.executable, "-c", code, str(tmp_path)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), [e for _, e in outs]
    builds = [line for out, _ in outs for line in out.splitlines() if line.startswith("building")]
    assert len(builds) == 2   # the Python twin and the native FMU, by one of the two
    assert is_native(tmp_path / "excitation.fmu")


def test_a_ready_spec_is_rebuilt_when_it_changes_and_only_then(tmp_path):
    # an extra FMU given as a spec (not a factory): its content joins the stamp
    from ctrlfmu.designs import design
    from ctrlfmu.fmuspec import law_spec

    law = design("testbed_isolation")
    built = ensure_fmus(["ctl"], tmp_path, extra={"ctl": law_spec(law, "ctl")},
                        kind="python")["ctl"]
    t0 = built.stat().st_mtime_ns
    ensure_fmus(["ctl"], tmp_path, extra={"ctl": law_spec(law, "ctl")}, kind="python")
    assert built.stat().st_mtime_ns == t0                     # same spec: not rebuilt
    other = law_spec(law.with_gain(2.0), "ctl")
    ensure_fmus(["ctl"], tmp_path, extra={"ctl": other}, kind="python")
    assert built.stat().st_mtime_ns != t0                     # another law: rebuilt
    with zipfile.ZipFile(built) as z:
        assert z.read("resources/law.npz") == other.resources["law.npz"]
