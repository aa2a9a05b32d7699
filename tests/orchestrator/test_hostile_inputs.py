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
from orchestrator.scenario import ScenarioError, read_ssp

ROOT = Path(__file__).resolve().parents[2]

MD = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="{version}" modelName="m" guid="{{1}}">
<CoSimulation modelIdentifier="{ident}" canGetAndSetFMUstate="true"/>
<UnitDefinitions><Unit name="V"><BaseUnit kg="1" m="2" s="-3" A="-1"/></Unit></UnitDefinitions>
<ModelVariables>
<ScalarVariable name="y" valueReference="1" causality="output" variability="discrete"
  initial="exact"><Real start="0" unit="V"/></ScalarVariable>
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


@pytest.fixture
def cache(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    monkeypatch.setenv("JITTERFMU_CACHE", str(root))
    monkeypatch.setattr(fmucache, "_VERIFIED", set())
    return root


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


@settings(max_examples=300, deadline=None)
@given(parts=st.lists(st.text(st.characters(blacklist_categories=("Cs",)), min_size=1,
                              max_size=8), min_size=1, max_size=5))
def test_property_member_names_without_dotdot_or_root_are_accepted(parts):
    name = "/".join(parts)
    problem = member_problem(name)
    clean = ("\x00" not in name and "\\" not in name and ".." not in name.split("/")
             and not name.startswith("/") and ":" not in name.split("/")[0])
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
