"""fmutools: an FMU carries the fmukit runtime only; the loader is compiled once."""

import ast
import zipfile
from pathlib import Path

import numpy as np
import pytest

from fmutools import compiled, loader
from fmutools.build import build_fmu
from fmutools.registry import collect_specs
from tests.support.hosts import run_c_host, run_fmpy

MODEL = "piezo_p243_40"
#: The runtime modules of fmukit, the only ones an FMU may carry.
RUNTIME = {"__init__.py", "modeldesc.py", "slave.py", "state.py", "timing.py", "units.py"}
#: Module names of the build, validation and test tooling.
TOOLING = {"build.py", "registry.py", "validate.py", "testing.py", "hosts.py",
           "fmucache.py", "loader.c"}


@pytest.fixture
def private_cache(tmp_path, monkeypatch):
    """An empty private cache for this test, and no loader remembered by the process."""
    root = tmp_path / "cache"
    monkeypatch.setenv("JITTERFMU_CACHE", str(root))
    monkeypatch.setattr(compiled, "_COMPILED", {})
    return root


@pytest.mark.slow
def test_fmu_carries_only_the_runtime_and_still_runs(tmp_path):
    fmu = build_fmu(collect_specs([MODEL])[0], tmp_path)
    with zipfile.ZipFile(fmu) as z:
        names = z.namelist()
    resources = [n.removeprefix("resources/") for n in names if n.startswith("resources/")]
    assert {n.removeprefix("fmukit/") for n in resources if n.startswith("fmukit/")} \
        == RUNTIME
    assert [n for n in resources if n.split("/")[0] == "fmutools"] == []
    assert [n for n in resources if n.rsplit("/", 1)[-1] in TOOLING] == []
    assert [n for n in names if n.endswith((".c", ".h"))] == []
    # the FMU runs from its own files: in fmpy, and in a C host without libpython
    kw = dict(inputs={"v_cmd": np.linspace(0.0, 50.0, 200), "elongation": 1e-7},
              outputs=["force", "voltage", "strain"], step_size=1e-3, n_steps=200)
    y = run_fmpy(fmu, **kw)
    assert np.all(np.isfinite(y)) and np.ptp(y[:, 1]) > 0
    np.testing.assert_array_equal(run_c_host(fmu, **kw), y)


def test_runtime_never_imports_the_tooling():
    """fmukit imports neither fmutools nor fmpy, so it runs inside an FMU on its own."""
    root = Path(__import__("fmukit").__file__).parent
    assert {p.name for p in root.glob("*.py")} == RUNTIME
    for path in root.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                tops = {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                tops = {(node.module or "").split(".")[0]}
            else:
                continue
            assert not tops & {"fmutools", "fmpy", "nativefmu", "orchestrator"}, path.name


def test_cached_loader_is_the_fresh_compile_and_is_compiled_once(private_cache, tmp_path,
                                                                 monkeypatch):
    cached = loader.cached_loader()
    assert cached.parent == private_cache and cached.name.startswith("loader-")
    fresh = loader.compile_loader(tmp_path / "fresh.so")
    assert cached.read_bytes() == fresh.read_bytes()

    def no_compile(*args, **kwargs):
        raise AssertionError("the loader was compiled again")

    monkeypatch.setattr(loader, "compile_loader", no_compile)
    assert loader.cached_loader() == cached
    monkeypatch.setattr(compiled, "_COMPILED", {})   # a new process finds it in the cache
    assert loader.cached_loader() == cached


def test_another_configuration_gets_its_own_loader(private_cache):
    config = loader.loader_config()
    other = loader.LoaderConfig({**config, "FMUKIT_SITE_DIRS": "/nonexistent"})
    first, second = loader.cached_loader(config), loader.cached_loader(other)
    assert first != second
    assert first.read_bytes() != second.read_bytes()
    assert sorted(p.name for p in private_cache.iterdir()) == sorted([first.name, second.name])


@pytest.mark.slow
def test_fmu_from_the_cached_loader_equals_one_from_a_fresh_compile(private_cache, tmp_path):
    spec = collect_specs([MODEL])[0]
    first = build_fmu(spec, tmp_path / "first")      # compiles the loader
    second = build_fmu(spec, tmp_path / "second")    # copies it from the cache
    fresh = loader.compile_loader(tmp_path / "fresh.so").read_bytes()
    binary = f"binaries/linux64/{MODEL}.so"
    with zipfile.ZipFile(first) as a, zipfile.ZipFile(second) as b:
        assert a.namelist() == b.namelist()
        assert a.read(binary) == b.read(binary) == fresh
        assert a.getinfo(binary).external_attr == b.getinfo(binary).external_attr
        for name in a.namelist():
            if name != "modelDescription.xml":   # holds the guid and the build time
                assert a.read(name) == b.read(name), name
