"""Hostile archives, cache entries and scenario files: refused in one sentence.

Each test builds its hostile input from scratch (no FMU is instantiated), so the file
runs in seconds.
"""

import os
import stat
import struct
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fmutools import fmucache
from fmutools.archive import (
    MEMBER_ENV,
    TOTAL_ENV,
    ArchiveError,
    SizeLimits,
    check_directory,
    inside,
    member_problem,
    model_identifier_problem,
)
from fmutools.fmucache import CacheError, extract_cached
from fmutools.validate import check_fmu
from orchestrator.cli import main
from orchestrator.cosim.fmuinfo import read_fmu_info
from orchestrator.scenario import ScenarioError, read_ssp, scenario_from_dict
from orchestrator.scenario.model import duplicates
from orchestrator.scenario.toml import MAX_FILE_ENV, MAX_FILE_MIB

ROOT = Path(__file__).resolve().parents[2]

MD = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="{version}" modelName="m" guid="{{1}}">
<CoSimulation modelIdentifier="{ident}" canGetAndSetFMUstate="true"/>
<UnitDefinitions><Unit name="V"><BaseUnit kg="1" m="2" s="-3" A="-1"/></Unit></UnitDefinitions>
<ModelVariables>
<ScalarVariable name="y" valueReference="1" causality="output" variability="discrete"
  initial="exact"><Real start="0" unit="V"/></ScalarVariable>
<ScalarVariable name="k" valueReference="2" causality="parameter" variability="fixed"
  initial="exact"><Real start="1" unit="V"/></ScalarVariable>
</ModelVariables>
<ModelStructure><Outputs><Unknown index="1" dependencies=""/></Outputs></ModelStructure>
</fmiModelDescription>
"""


def make_fmu(path, ident="m", version="2.0", extra=None):
    """A model description and a (fake) binary: enough for every check before loading."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", MD.format(ident=ident, version=version))
        z.writestr(f"binaries/linux64/{Path(ident).name}.so", b"\x7fELF")
        for name, data in (extra or {}).items():
            z.writestr(name, data)
    return path


def one_instance(tmp_path, fmu):
    scenario = tmp_path / "s.toml"
    scenario.write_text(f'[experiment]\nstop = 0.01\noutput_interval = 1e-3\n'
                        f'[fmus.a]\nfmu = "{fmu}"\nperiod = 1e-3\n'
                        '[record]\nvariables = ["a.y"]\n')
    return scenario


# ------------------------------------------------------------------ 8. paths out of the archive

@pytest.mark.parametrize("ident", ["../../../../tmp/evil", "/tmp/evil", "a/b", "a.b", "1x", ""])
def test_a_model_identifier_that_names_a_file_elsewhere_is_refused_by_every_command(
        tmp_path, cache, capsys, ident):
    fmu = make_fmu(tmp_path / "bad.fmu", ident)
    with pytest.raises(ScenarioError, match="modelIdentifier .* is not a C identifier"):
        read_fmu_info(fmu)
    errors, _ = check_fmu(fmu)
    assert len(errors) == 1 and "is not a C identifier" in errors[0]
    capsys.readouterr()
    assert main(["validate", str(fmu)]) == 1
    assert "is not a C identifier" in capsys.readouterr().out
    scenario = one_instance(tmp_path, fmu)
    for argv in (["run", str(scenario), "--out", str(tmp_path / "out"), "--quiet"],
                 ["analyze", str(scenario), "--no-margins"]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "is not a C identifier" in err and "Traceback" not in err
    assert not (tmp_path / "out" / "results.parquet").exists()


@pytest.mark.parametrize("member", ["../escape.txt", "/abs.txt", "resources/../../x"])
def test_an_fmu_member_outside_the_archive_is_refused_by_validate_and_run(tmp_path, cache,
                                                                          capsys, member):
    fmu = make_fmu(tmp_path / "bad.fmu", extra={member: b"x"})
    assert main(["validate", str(fmu)]) == 1
    assert f"holds the unsafe path {member!r}" in capsys.readouterr().out
    scenario = one_instance(tmp_path, fmu)
    assert main(["run", str(scenario), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert f"holds the unsafe path {member!r}" in capsys.readouterr().err
    assert not (tmp_path / "escape.txt").exists()


def test_a_c_identifier_is_a_valid_model_identifier(tmp_path):
    assert model_identifier_problem("truss10_structure") is None
    assert read_fmu_info(make_fmu(tmp_path / "ok.fmu", "_Ok_1")).model_identifier == "_Ok_1"
    assert check_fmu(make_fmu(tmp_path / "ok2.fmu", "ok2")).errors == ()


SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
  xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
  xmlns:osp="https://opensimulationplatform.com/SSP/OSPAnnotations" name="s" version="1.0">
<ssd:System name="s"><ssd:Elements>{components}</ssd:Elements></ssd:System>
<ssd:DefaultExperiment startTime="0" stopTime="0.01"/>
</ssd:SystemStructureDescription>
"""
COMPONENT = """<ssd:Component name="{name}" source="{source}"
  type="application/x-fmu-sharedlibrary">{bindings}<ssd:Annotations>
  <ssc:Annotation type="com.opensimulationplatform"><osp:StepSizeHint value="0.001"/>
  </ssc:Annotation></ssd:Annotations></ssd:Component>"""


def make_ssp(path, components, files=None):
    """``components``: [(name, source, binding source or None)]."""
    body = ""
    for name, source, binding in components:
        bindings = ("" if binding is None else
                    f'<ssd:ParameterBindings><ssd:ParameterBinding source="{binding}"/>'
                    "</ssd:ParameterBindings>")
        body += COMPONENT.format(name=name, source=source, bindings=bindings)
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("SystemStructure.ssd", SSD.format(components=body))
        for name, data in (files or {}).items():
            z.writestr(name, data)
    return path


@pytest.mark.parametrize("source", ["../outside.fmu", "resources/../../outside.fmu",
                                    "/tmp/outside.fmu", "file:///tmp/outside.fmu",
                                    "resources\\..\\..\\outside.fmu"])
def test_an_ssp_component_source_outside_the_archive_is_refused(tmp_path, cache, capsys,
                                                                 source):
    make_fmu(tmp_path / "outside.fmu")   # what the source would reach
    ssp = make_ssp(tmp_path / "x.ssp", [("a", source, None)])
    with pytest.raises(ScenarioError, match="source of component 'a' .* is unsafe"):
        read_ssp(ssp)
    for argv in (["run", str(ssp), "--out", str(tmp_path / "out"), "--quiet"],
                 ["analyze", str(ssp), "--no-margins"]):
        assert main(argv) == 2
        assert "is unsafe" in capsys.readouterr().err
    assert main(["validate", str(ssp)]) == 1
    assert "is unsafe" in capsys.readouterr().out


def test_validate_checks_the_component_fmus_of_an_ssp_archive(tmp_path, cache, capsys):
    inner = make_fmu(tmp_path / "inner.fmu", "inner")
    ssp = make_ssp(tmp_path / "ok.ssp", [("a", "resources/a.fmu", None)],
                   {"resources/a.fmu": inner.read_bytes()})
    assert main(["validate", str(ssp)]) == 0
    bad = make_fmu(tmp_path / "bad.fmu", "../bad")
    ssp = make_ssp(tmp_path / "bad.ssp", [("a", "resources/a.fmu", None)],
                   {"resources/a.fmu": bad.read_bytes()})
    capsys.readouterr()
    assert main(["validate", str(ssp)]) == 1
    assert "modelIdentifier '../bad' is not a C identifier" in capsys.readouterr().out


@pytest.mark.parametrize("binding", ["../secret.ssv", "/etc/hostname", "resources/../../x"])
def test_an_ssp_parameter_binding_outside_the_archive_is_refused(tmp_path, cache, binding):
    ssp = make_ssp(tmp_path / "x.ssp", [("a", "resources/a.fmu", binding)],
                   {"resources/a.fmu": b"x"})
    (tmp_path / "secret.ssv").write_text("<ssv:ParameterSet/>")
    with pytest.raises(ScenarioError, match="parameter binding source of component 'a' .* "
                                            "is unsafe"):
        read_ssp(ssp)


def test_an_extracted_ssp_folder_may_not_link_out_of_itself(tmp_path):
    folder = tmp_path / "sys"
    folder.mkdir()
    (folder / "SystemStructure.ssd").write_text(
        SSD.format(components=COMPONENT.format(name="a", source="resources/a.fmu",
                                                bindings="")))
    (tmp_path / "elsewhere").mkdir()
    (folder / "resources").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(ScenarioError, match="symbolic link out of the archive"):
        read_ssp(folder)


def test_an_ssp_source_with_a_dot_part_stays_inside_and_is_read(tmp_path, cache):
    ssp = make_ssp(tmp_path / "x.ssp", [("a", "./resources//a.fmu", None)],
                   {"resources/a.fmu": b"x"})
    fmu = Path(read_ssp(ssp).instance("a").fmu)
    assert fmu.name == "a.fmu" and fmu.parent.name == "resources"


def test_two_ssp_components_with_one_name_are_refused(tmp_path, cache):
    ssp = make_ssp(tmp_path / "x.ssp", [("a", "resources/a.fmu", None),
                                        ("a", "resources/b.fmu", None)])
    with pytest.raises(ScenarioError, match="two components named 'a'"):
        read_ssp(ssp)


SEGMENT = st.sampled_from(["..", ".", "a", "b.fmu", "", "C:", "x\\y", "res"])


@settings(max_examples=300, deadline=None)
@given(parts=st.lists(SEGMENT, min_size=1, max_size=6), absolute=st.booleans())
def test_property_inside_never_names_a_file_outside_the_folder(tmp_path_factory, parts,
                                                                absolute):
    folder = tmp_path_factory.mktemp("arch")
    ref = ("/" if absolute else "") + "/".join(parts)
    try:
        target = inside(folder, ref, "ref")
    except ArchiveError as exc:
        assert "is unsafe" in str(exc)
        assert member_problem(ref) is not None or ".." in ref
        return
    assert target.resolve().is_relative_to(folder.resolve())
    assert not absolute and ".." not in parts and "\\" not in ref


@settings(max_examples=100, deadline=None)
@given(names=st.lists(st.lists(SEGMENT, min_size=1, max_size=4).map("/".join).filter(bool),
                      min_size=1,
                      max_size=4, unique=True))
def test_property_an_archive_unpacks_inside_its_entry_or_not_at_all(tmp_path_factory, names):
    base = tmp_path_factory.mktemp("unpack")
    work = base / "deep" / "er"
    work.mkdir(parents=True)
    fmu = work / "a.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.writestr("modelDescription.xml", "<fmiModelDescription/>")
        for name in names:
            if name != "modelDescription.xml":
                z.writestr(name, b"x")
    before = {p for p in base.rglob("*") if "cache" not in p.relative_to(base).parts}
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("JITTERFMU_CACHE", str(base / "cache"))
        mp.setattr(fmucache, "_VERIFIED", set())
        try:
            dest = extract_cached(fmu)
        except CacheError as exc:
            assert ("unsafe path" in str(exc) or "both as a file and as a folder" in str(exc)
                    or "no modelDescription.xml" in str(exc)), exc
            assert list((base / "cache").iterdir()) == []
        else:
            assert all(path.resolve().is_relative_to(dest.resolve())
                       for path in dest.rglob("*"))
    after = {p for p in base.rglob("*") if "cache" not in p.relative_to(base).parts}
    assert after == before


@settings(max_examples=300, deadline=None)
@given(parts=st.lists(st.text(st.characters(blacklist_categories=("Cs",)), min_size=1,
                              max_size=8), min_size=1, max_size=5))
def test_property_member_names_without_dotdot_or_root_are_accepted(parts):
    name = "/".join(parts)
    problem = member_problem(name)
    split = name.split("/")
    split = split[:-1] if split[-1] == "" else split   # a trailing / marks a folder
    clean = ("\x00" not in name and "\\" not in name and not {"..", ".", ""} & set(split)
             and not name.startswith("/") and ":" not in split[0])
    if clean:
        assert problem is None
    if ".." in name.split("/") or name.startswith("/"):
        assert problem is not None


@settings(max_examples=200, deadline=None)
@given(ident=st.text(max_size=12))
def test_property_a_model_identifier_is_accepted_only_as_a_c_identifier(ident):
    ok = model_identifier_problem(ident) is None
    assert ok == (ident.isascii() and ident.isidentifier())


# ------------------------------------------------------------------ 9. zip sizes

def zeros_archive(path, sizes):
    """Members of zeros (they compress to almost nothing)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", "<fmiModelDescription/>")
        for name, size in sizes.items():
            z.writestr(name, bytes(size))
    return path


def test_a_member_above_the_limit_is_refused_naming_it_its_size_and_the_way_out(
        tmp_path, cache, monkeypatch):
    fmu = zeros_archive(tmp_path / "big.fmu", {"resources/big.bin": 3 << 20})
    assert fmu.stat().st_size < 20_000
    monkeypatch.setenv(MEMBER_ENV, "1")
    with pytest.raises(CacheError) as err:
        extract_cached(fmu)
    msg = str(err.value)
    assert "'resources/big.bin' unpacks to 3.0 MiB" in msg
    assert "limit of 1.0 MiB per member" in msg and f"{MEMBER_ENV}=" in msg
    assert list(cache.iterdir()) == []          # nothing unpacked, nothing kept
    monkeypatch.setenv(MEMBER_ENV, "4")         # raised: it unpacks
    assert (extract_cached(fmu) / "resources/big.bin").stat().st_size == 3 << 20


def test_the_total_size_of_an_archive_is_limited(tmp_path, cache, monkeypatch):
    fmu = zeros_archive(tmp_path / "many.fmu", {f"resources/{i}.bin": 1 << 20
                                                for i in range(3)})
    monkeypatch.setenv(TOTAL_ENV, "2.5")
    with pytest.raises(CacheError, match=f"limit of 2.5 MiB per archive .*{TOTAL_ENV}="):
        extract_cached(fmu)
    assert list(cache.iterdir()) == []


def test_the_default_limits_refuse_the_2_gib_member_of_the_report():
    limits = SizeLimits()
    assert 64 << 20 <= limits.member < 2 << 30 <= limits.total


def _lie_about_size(path, declared):
    """Rewrite the uncompressed size of the archive's last member in its headers."""
    data = bytearray(path.read_bytes())
    cd = data.rfind(b"PK\x01\x02")         # last central directory entry
    struct.pack_into("<I", data, cd + 24, declared)
    lh = struct.unpack_from("<I", data, cd + 42)[0]
    struct.pack_into("<I", data, lh + 22, declared)
    path.write_bytes(bytes(data))


def test_a_directory_entry_declaring_gigabytes_is_refused_before_anything_is_unpacked(
        tmp_path, cache):
    fmu = zeros_archive(tmp_path / "huge.fmu", {"resources/huge.bin": 10})
    _lie_about_size(fmu, 0xFFFFFFF0)            # 4 GiB, declared by a 1 kB file
    with pytest.raises(CacheError, match=r"'resources/huge.bin' unpacks to 4.0 GiB"):
        extract_cached(fmu)
    assert list(cache.iterdir()) == []
    errors, _ = check_fmu(fmu)
    assert "unpacks to 4.0 GiB" in errors[0]
    with pytest.raises(ScenarioError, match="unpacks to 4.0 GiB"):
        read_fmu_info(fmu)


def test_a_member_that_unpacks_to_more_than_its_header_says_is_refused(tmp_path, cache,
                                                                       monkeypatch):
    fmu = zeros_archive(tmp_path / "liar.fmu", {"resources/liar.bin": 3 << 20})
    _lie_about_size(fmu, 1000)                  # passes the directory check
    monkeypatch.setenv(MEMBER_ENV, "1")
    with zipfile.ZipFile(fmu) as z:
        check_directory(z, "liar", SizeLimits.from_env())
    with pytest.raises(CacheError, match="liar.bin"):
        extract_cached(fmu)
    assert list(cache.iterdir()) == []


# ------------------------------------------------------------------ 10. compiled cache entries

def test_a_group_or_world_writable_compiled_library_is_compiled_again(cache):
    from fmutools import compiled

    calls = []

    def compile_to(out):
        calls.append(out)
        out.write_bytes(b"good library")

    first = compiled.compiled_once("fastloop", "k1", compile_to)
    assert stat.S_IMODE(first.stat().st_mode) & 0o022 == 0
    compiled._COMPILED.clear()
    first.write_bytes(b"planted by someone else")
    os.chmod(first, 0o777)
    again = compiled.compiled_once("fastloop", "k1", compile_to)
    assert len(calls) == 2 and again.read_bytes() == b"good library"
    assert stat.S_IMODE(again.stat().st_mode) & 0o022 == 0
    os.chmod(again, 0o775)                       # group-writable: refused too
    compiled._COMPILED.clear()
    compiled.compiled_once("fastloop", "k1", compile_to)
    assert len(calls) == 3


def test_a_refused_cache_leaves_no_temporary_folder_behind(tmp_path):
    """With no usable cache the library goes to a folder of the process, removed at exit."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")   # a cache that is refused
    code = ("from fmutools.compiled import compiled_once\n"
            "p = compiled_once('loader', 'k', lambda out: out.write_bytes(b'x'))\n"
            "assert p.read_bytes() == b'x'\n")
    env = {**os.environ, "TMPDIR": str(tmp), "JITTERFMU_CACHE": str(tmp_path / "link")}
    subprocess.run([sys.executable, "-c", code], check=True, env=env, cwd=ROOT)
    assert sorted(p.name for p in tmp.iterdir()) == []


# ------------------------------------------------------------------ 13. huge scenarios

class CountedName(str):
    """A name that counts its equality comparisons and stops a quadratic check early."""

    compared = 0
    budget = 0

    def __eq__(self, other):
        type(self).compared += 1
        if type(self).compared > type(self).budget:
            raise AssertionError(f"more than {type(self).budget} comparisons: quadratic")
        return str.__eq__(self, other)

    __hash__ = str.__hash__


def test_the_duplicate_check_of_20000_recorded_variables_is_linear():
    import random

    names = [CountedName(f"a.v{i}") for i in range(20_000)]
    names += [CountedName("a.v7"), CountedName("a.v19999"), CountedName("a.v7")]
    random.Random(1).shuffle(names)
    CountedName.compared, CountedName.budget = 0, 4 * len(names)
    data = {"experiment": {"stop": 1, "output_interval": 0.1},
            "fmus": {"a": {"fmu": "x", "period": 0.1}}, "record": {"variables": names}}
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict(data)
    assert CountedName.compared <= CountedName.budget
    msg = str(err.value)
    assert "'a.v7'" in msg and "'a.v19999'" in msg and msg.count("'a.v") == 2


def test_duplicates_reports_each_repeated_item_once():
    assert duplicates(["a", "b", "a", "c", "b", "a"]) == ["a", "b"]
    assert duplicates([f"x{i}" for i in range(20_000)]) == []


def test_a_scenario_file_above_the_size_limit_is_refused_in_one_sentence(tmp_path, capsys,
                                                                         monkeypatch):
    big = tmp_path / "big.toml"
    big.write_text("[experiment]\nstop = 1\noutput_interval = 0.1\n"
                   + "".join(f"# padding line {i}\n" for i in range(20_000)))
    monkeypatch.setenv(MAX_FILE_ENV, "0.1")
    assert main(["run", str(big), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "is 0.4 MiB, above the limit of 0.1 MiB for a scenario" in err
    assert MAX_FILE_ENV in err and len(err.splitlines()) == 2
    assert MAX_FILE_MIB >= 8    # the default leaves room for any real scenario


# ------------------------------------------------------------------ 14. messages

def cli_error(capsys, argv):
    """Exit code and stderr of the command line, which must be one sentence."""
    code = main(argv)
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return code, err


MINIMAL = "[experiment]\nstop = 0.01\noutput_interval = 1e-3\n"


def test_fmus_table_entry_that_is_not_a_table_is_named(tmp_path, capsys):
    bad = tmp_path / "s.toml"
    bad.write_text(MINIMAL + "[fmus]\nstructure = 5\n")
    code, err = cli_error(capsys, ["run", str(bad), "--out", str(tmp_path / "o")])
    assert code == 2 and "s.toml: [fmus.structure] must be a table; got int 5" in err


def test_a_non_utf8_scenario_is_named_with_the_line_of_the_bad_byte(tmp_path, capsys):
    bad = tmp_path / "latin1.toml"
    bad.write_bytes(MINIMAL.encode() + '[fmus.a]\nfmu = "café"\n'.encode("latin-1"))
    code, err = cli_error(capsys, ["run", str(bad), "--out", str(tmp_path / "o")])
    assert code == 2 and "latin1.toml' is not text (not UTF-8) from byte" in err and "on line 5" in err


@pytest.mark.parametrize("value", ["[" * 5000 + "]" * 5000, "{a=" * 3000 + "1" + "}" * 3000])
def test_deep_nesting_is_one_sentence_naming_the_file(tmp_path, capsys, value):
    deep = tmp_path / "deep.toml"
    deep.write_text(MINIMAL + f"x = {value}\n")
    code, err = cli_error(capsys, ["run", str(deep), "--out", str(tmp_path / "o")])
    assert code == 2
    assert "deep.toml' nests arrays or tables deeper than can be read" in err
    assert "recursion" not in err


def test_a_100_kb_file_name_is_not_echoed_whole(tmp_path, capsys):
    name = "a" * 100_000 + ".toml"
    code, err = cli_error(capsys, ["run", name, "--out", str(tmp_path / "o")])
    assert code == 2 and len(err) < 600 and "(100005 characters)" in err
    assert "File name too long" in err or "does not exist" in err


def test_a_wrong_guid_names_both_guids_and_what_to_do(tmp_path, capsys, cache, suite_fmus):
    import re

    src = suite_fmus("excitation")["excitation"]
    fmu = tmp_path / "guid.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                data = re.sub(rb'guid="[^"]*"', b'guid="{0-wrong}"', data)
            zout.writestr(item.filename, data)
    scenario = tmp_path / "s.toml"
    scenario.write_text(MINIMAL + f'[fmus.e]\nfmu = "{fmu}"\nperiod = 1e-3\n'
                        '[record]\nvariables = ["e.v1"]\n')
    code, err = cli_error(capsys, ["run", str(scenario), "--out", str(tmp_path / "o"),
                                   "--quiet"])
    assert code == 1
    assert "GUID {0-wrong} does not match the model's" in err
    assert "rebuild the FMU" in err


FMI3 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="m" instantiationToken="{1}">
<CoSimulation modelIdentifier="m"/>
<ModelVariables>
<Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
<Float64 name="y" valueReference="1" causality="output" variability="continuous"/>
</ModelVariables>
<ModelStructure><Output valueReference="1"/><InitialUnknown valueReference="1"/>
</ModelStructure>
</fmiModelDescription>
"""


def test_an_fmi3_fmu_is_read_and_its_broken_binary_named_by_run(tmp_path, capsys):
    fmu = tmp_path / "three.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.writestr("modelDescription.xml", FMI3)
        z.writestr("binaries/x86_64-linux/m.so", b"\x7fELF")
    info = read_fmu_info(fmu)   # the master runs FMI 3.0 FMUs (tests/nativefmu/test_fmi3.py)
    assert info.fmi_version == "3.0" and info.variables["y"].type == "Real"
    code, err = cli_error(capsys, ["run", str(one_instance(tmp_path, fmu)), "--out",
                                   str(tmp_path / "o")])
    assert code == 1 and "could not be loaded from three.fmu" in err


def test_validate_names_the_conventions_an_fmi3_fmu_misses(tmp_path, capsys):
    fmu = tmp_path / "three.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.writestr("modelDescription.xml", FMI3)
    assert main(["validate", "--strict", str(fmu)]) == 1
    out = capsys.readouterr()
    text = out.out + out.err
    assert "Float64 variable 'y' has no unit" in text
    assert "output 'y' has no dependencies attribute" in text


def test_an_fmi4_fmu_is_named_as_such(tmp_path):
    fmu = tmp_path / "four.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.writestr("modelDescription.xml", FMI3.replace('fmiVersion="3.0"', 'fmiVersion="4.0"'))
    with pytest.raises(ScenarioError, match="is FMI 4.0, and this master runs FMI 2.0 and "
                                            "3.0 FMUs only"):
        read_fmu_info(fmu)


def test_a_non_finite_structure_matrix_is_named_by_its_field_and_file(tmp_path):
    import numpy as np

    from structfmu.errors import ModelError
    from structfmu.reduced import ReducedModel

    fields = {"omega": [10.0, 20.0], "modal_damping": [0.01, 0.01], "B_e": [[1.0], [0.5]],
              "C_e": [[1.0, 0.0]], "K_oo": np.zeros((0, 0)), "D_oo": np.zeros((0, 0)),
              "B_o": np.zeros((0, 1)), "C_o": np.zeros((1, 0)), "input_names": ("f",),
              "output_names": ("y",), "output_kinds": ("disp",), "name": "tiny"}
    path = ReducedModel(**fields).save(tmp_path / "tiny.npz")
    with pytest.raises(ModelError, match=r"C_e has a non-finite entry \(nan at index \(0, 1\)"):
        ReducedModel(**{**fields, "C_e": [[1.0, np.nan]]})
    data = dict(np.load(path, allow_pickle=False))
    data["C_e"] = np.array([[1.0, np.inf]])
    np.savez(tmp_path / "bad.npz", **data)
    with pytest.raises(ModelError, match=r"bad.npz': reduced model 'tiny': C_e has a "
                                         r"non-finite entry \(inf"):
        ReducedModel.load(tmp_path / "bad.npz")


def test_recorded_warnings_print_once_each_with_their_count(capsys):
    import warnings

    from orchestrator.cli import report_warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(2652):
            warnings.warn("overflow encountered in reduce (test 14)", RuntimeWarning,
                          stacklevel=1)
        warnings.warn("an ordinary warning (test 14)", UserWarning, stacklevel=1)
    report_warnings(caught)
    err = capsys.readouterr().err.splitlines()
    assert err == [("jitterfmu: warning: overflow encountered in reduce (test 14) "
                    "(RuntimeWarning, 2652 times)"),
                   "jitterfmu: warning: an ordinary warning (test 14)"]


WORKERS = """
import multiprocessing
import warnings

import numpy as np

import orchestrator.cli  # what the console script imports: it sets up warnings


class UnconnectedInputWarning(UserWarning):
    pass


def case(i):
    warnings.warn("2 input(s) are not connected", UnconnectedInputWarning)
    np.float64(1e308) * np.float64(10)   # numpy's RuntimeWarning
    return i


if __name__ == "__main__":
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(2) as pool:
        assert pool.map(case, range(4)) == list(range(4))
    warnings.warn("2 input(s) are not connected", UnconnectedInputWarning)
    warnings.warn("2 input(s) are not connected", UnconnectedInputWarning)
"""


def test_warnings_are_one_line_without_source_and_wiring_is_said_once_per_run(tmp_path):
    script = tmp_path / "workers.py"
    script.write_text(WORKERS)
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          cwd=ROOT, timeout=120, check=True)
    lines = proc.stderr.splitlines()
    assert lines.count("jitterfmu: warning: 2 input(s) are not connected") == 1
    overflow = [ln for ln in lines if "overflow" in ln]
    assert overflow and all(ln.startswith("jitterfmu: warning: overflow") for ln in overflow)
    assert len(overflow) <= 2                        # at most once per worker
    assert all(ln.startswith("jitterfmu: warning: ") for ln in lines), lines


def test_an_error_without_text_still_prints_a_sentence(monkeypatch, capsys):
    """numpy or zipfile out of memory raise MemoryError() with no message at all."""
    from orchestrator.cli import validate

    def out_of_memory(args):
        raise MemoryError()

    monkeypatch.setattr(validate, "run", out_of_memory)
    assert main(["validate", "x.fmu"]) == 2
    err = capsys.readouterr().err.splitlines()[0]
    assert err == ("jitterfmu: error: out of memory; make the run, its record or its input "
                   "smaller, or free memory")


def test_the_master_never_loads_a_world_writable_compiled_loop(tmp_path):
    """A fastloop entry that others could have rewritten is compiled again, not loaded."""
    code = ("from orchestrator.cosim.fastloop import compiled_library\n"
            "assert compiled_library() is not None\n")
    env = {**os.environ, "JITTERFMU_CACHE": str(tmp_path / "cache")}
    subprocess.run([sys.executable, "-c", code], check=True, env=env, cwd=ROOT, timeout=300)
    (entry,) = (tmp_path / "cache").glob("fastloop-*.so")
    entry.write_bytes(b"not a library: what another user wrote")
    os.chmod(entry, 0o777)
    subprocess.run([sys.executable, "-c", code], check=True, env=env, cwd=ROOT, timeout=300)
    assert entry.read_bytes()[:4] == b"\x7fELF"
    assert stat.S_IMODE(entry.stat().st_mode) & 0o022 == 0


@pytest.mark.parametrize("value", ["1e309", "nan", "-inf"])
def test_a_start_value_that_overflows_is_refused_before_the_run(tmp_path, cache, capsys,
                                                                value):
    scenario = one_instance(tmp_path, make_fmu(tmp_path / "k.fmu", "k"))
    code, err = cli_error(capsys, ["run", str(scenario), "--out", str(tmp_path / "o"),
                                   "--quiet", "--set", f"a.k={value}"])
    assert code == 2 and "a.k is Real; got" in err and "expected a finite number" in err


def test_an_ssp_system_structure_above_the_size_limit_is_refused(tmp_path, cache,
                                                                 monkeypatch):
    many = "".join(COMPONENT.format(name=f"c{i}", source="resources/a.fmu", bindings="")
                   for i in range(400))
    ssp = tmp_path / "big.ssp"
    with zipfile.ZipFile(ssp, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("SystemStructure.ssd", SSD.format(components=many))
    monkeypatch.setenv(MAX_FILE_ENV, "0.05")
    with pytest.raises(ScenarioError, match=r"big.ssp/SystemStructure.ssd is 0.1 MiB, above "
                                            r"the limit of 0.05 MiB for a scenario"):
        read_ssp(ssp)


def test_deep_nesting_anywhere_is_one_sentence_not_pythons(tmp_path, capsys):
    """A campaign file is read as scenarios are: one sentence naming it and what to do."""
    deep = tmp_path / "deep_campaign.toml"
    deep.write_text('[campaign]\nname = "x"\nx = ' + "[" * 5000 + "]" * 5000 + "\n")
    code, err = cli_error(capsys, ["campaign", str(deep), "--out", str(tmp_path / "o")])
    assert code == 2
    assert "deep_campaign.toml' nests arrays or tables deeper than can be read; flatten it" \
        in err
    assert "recursion" not in err
