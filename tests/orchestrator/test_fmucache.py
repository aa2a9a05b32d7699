"""The private extraction cache: no planted, shared or half-written folder is ever used."""

import hashlib
import json
import os
import shutil
import stat
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
import tomli_w

from fmutools import fmucache
from fmutools.fmucache import MANIFEST, CacheError, cache_root, extract_cached
from orchestrator.scenario import ScenarioError, read_ssp

ROOT = Path(__file__).resolve().parents[2]


def make_archive(path, files):
    with zipfile.ZipFile(path, "w") as z:
        for name, data in files.items():
            z.writestr(name, data)
    return path


FILES = {"modelDescription.xml": "<fmiModelDescription/>",
         "resources/slave.py": "VALUE = 1\n"}


def leftovers(root):
    return sorted(p.name for p in root.iterdir() if p.name.startswith("."))


def test_extracts_once_into_a_private_folder_and_reuses_it(cache, tmp_path):
    fmu = make_archive(tmp_path / "a.fmu", FILES)
    sha = hashlib.sha256(fmu.read_bytes()).hexdigest()
    dest = extract_cached(fmu, sha)
    assert dest == cache / f"fmu-{sha}"
    assert (dest / "resources/slave.py").read_text() == "VALUE = 1\n"
    assert stat.S_IMODE(cache.stat().st_mode) == 0o700
    assert stat.S_IMODE(dest.stat().st_mode) == 0o700
    mtime = (dest / "resources/slave.py").stat().st_mtime_ns
    fmucache._VERIFIED.clear()
    assert extract_cached(fmu, sha) == dest  # checked, not unpacked again
    assert (dest / "resources/slave.py").stat().st_mtime_ns == mtime
    assert leftovers(cache) == []


@pytest.mark.parametrize("tamper", ["edit", "add", "forged-manifest", "symlink"])
def test_tampered_or_planted_entry_is_replaced_before_use(cache, tmp_path, tamper):
    fmu = make_archive(tmp_path / "a.fmu", FILES)
    sha = hashlib.sha256(fmu.read_bytes()).hexdigest()
    dest = extract_cached(fmu, sha)
    fmucache._VERIFIED.clear()
    slave = dest / "resources/slave.py"
    if tamper == "edit":
        slave.write_text("import os; os.system('touch pwned')\n")
    elif tamper == "add":
        (dest / "resources/sitecustomize.py").write_text("raise SystemExit\n")
    elif tamper == "forged-manifest":  # a planted folder that lists its own hashes
        evil = b"import os; os.system('touch pwned')\n"
        slave.write_bytes(evil)
        manifest = json.loads((dest / MANIFEST).read_text())
        manifest["files"]["resources/slave.py"] = hashlib.sha256(evil).hexdigest()
        (dest / MANIFEST).write_text(json.dumps(manifest))
    else:
        slave.unlink()
        (tmp_path / "evil.py").write_text("VALUE = 1\n")
        slave.symlink_to(tmp_path / "evil.py")
    assert extract_cached(fmu, sha) == dest
    assert not slave.is_symlink()
    assert slave.read_text() == "VALUE = 1\n"
    assert sorted(p.name for p in (dest / "resources").iterdir()) == ["slave.py"]
    assert leftovers(cache) == []


def test_pycache_written_by_python_does_not_invalidate_an_entry(cache, tmp_path):
    fmu = make_archive(tmp_path / "a.fmu", FILES)
    dest = extract_cached(fmu)
    (dest / "resources/__pycache__").mkdir()
    (dest / "resources/__pycache__/slave.cpython-311.pyc").write_bytes(b"\0")
    fmucache._VERIFIED.clear()
    extract_cached(fmu)
    assert (dest / "resources/__pycache__/slave.cpython-311.pyc").exists()


@pytest.mark.skipif(os.getuid() != 0, reason="giving a folder to another user needs root")
def test_cache_owned_by_another_user_is_refused(cache):
    cache.mkdir(mode=0o700)
    os.chown(cache, 65534, 65534)
    with pytest.raises(CacheError, match="belongs to user id 65534, not to you"):
        cache_root()


def test_cache_that_others_can_write_is_made_private(cache):
    cache.mkdir()
    os.chmod(cache, 0o777)
    assert cache_root() == cache
    assert stat.S_IMODE(cache.stat().st_mode) == 0o700


def test_symlinked_cache_is_refused(cache, tmp_path):
    (tmp_path / "elsewhere").mkdir(mode=0o700)
    cache.symlink_to(tmp_path / "elsewhere")
    with pytest.raises(CacheError, match="not a directory"):
        cache_root()


def test_default_cache_is_the_xdg_cache_folder(tmp_path, monkeypatch):
    monkeypatch.delenv("JITTERFMU_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_root() == tmp_path / "xdg" / "jitterfmu"


@pytest.mark.parametrize("files, message", [
    (None, "is not a zip archive"),
    ({"resources/slave.py": "x"}, "has no modelDescription.xml"),
    ({"modelDescription.xml": "x", "../escape.py": "x"}, "unsafe path '../escape.py'"),
    ({"modelDescription.xml": "x", "/abs.py": "x"}, "unsafe path '/abs.py'"),
])
def test_failed_extraction_leaves_nothing_behind(cache, tmp_path, files, message):
    fmu = tmp_path / "sub" / "a.fmu"
    fmu.parent.mkdir()
    if files is None:
        fmu.write_bytes(b"not a zip")
    else:
        make_archive(fmu, files)
    with pytest.raises(CacheError, match=message):
        extract_cached(fmu)
    assert list(cache.iterdir()) == []
    assert not (tmp_path / "escape.py").exists()


def test_archive_that_changed_since_it_was_hashed_is_refused(cache, tmp_path):
    fmu = make_archive(tmp_path / "a.fmu", FILES)
    with pytest.raises(CacheError, match="changed while it was read"):
        extract_cached(fmu, "0" * 64)
    assert list(cache.iterdir()) == []


def test_ssp_extraction_uses_the_private_cache_and_cleans_up(cache, tmp_path):
    bad = tmp_path / "bad.ssp"
    bad.write_bytes(b"not a zip")
    with pytest.raises(ScenarioError, match="is not a zip archive"):
        read_ssp(bad)
    nossd = make_archive(tmp_path / "nossd.ssp", {"x.txt": "x"})
    with pytest.raises(ScenarioError, match="has no SystemStructure.ssd"):
        read_ssp(nossd)
    assert list(cache.iterdir()) == []
    planted = make_archive(tmp_path / "p.ssp", {"SystemStructure.ssd": "<a/>"})
    with pytest.raises(ScenarioError, match="not an SSP 1.0"):
        read_ssp(planted)
    (entry,) = cache.iterdir()
    assert entry.name.startswith("ssp-") and stat.S_IMODE(entry.stat().st_mode) == 0o700


@pytest.mark.slow
def test_run_never_executes_code_planted_in_the_cache(fmu_dir, tmp_path):
    """Issue 12: a folder planted where the master looks for the extracted FMU had its
    slave code run by ``jitterfmu run``."""
    fmu = fmu_dir / "MtIntegrator.fmu"
    sha = hashlib.sha256(fmu.read_bytes()).hexdigest()
    cache = tmp_path / "cache"
    cache.mkdir(mode=0o700)
    planted = cache / f"fmu-{sha}"
    with zipfile.ZipFile(fmu) as z:
        z.extractall(planted)
    os.chmod(planted, 0o700)
    marker = tmp_path / "pwned"
    slave = planted / "resources/mastertest_slaves/__init__.py"
    evil = f"import pathlib; pathlib.Path({str(marker)!r}).touch()\n" + slave.read_text()
    slave.write_text(evil)
    files = {p.relative_to(planted).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
             for p in planted.rglob("*") if p.is_file()}
    (planted / MANIFEST).write_text(json.dumps({"archive_sha256": sha, "files": files}))
    scen = tmp_path / "s.toml"
    scen.write_text(tomli_w.dumps({
        "experiment": {"stop": 0.01, "output_interval": 1e-3},
        "fmus": {"plant": {"fmu": "MtIntegrator", "period": 1e-3,
                           "parameters": {"u": 1.0}}},
        "record": {"variables": ["plant.x"]},
    }))
    # the same folder where the old code looked: jitterfmu-fmu-<16 hex> in the temp folder
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    shutil.copytree(planted, tmp / f"jitterfmu-fmu-{sha[:16]}")
    env = dict(os.environ, JITTERFMU_CACHE=str(cache), TMPDIR=str(tmp))
    proc = subprocess.run([sys.executable, "-c", "import sys; from orchestrator.cli import main; "
                           "sys.exit(main(sys.argv[1:]))", "run", str(scen),
                           "--out", str(tmp_path / "o"), "--fmu-dir", str(fmu_dir), "--quiet"],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert not marker.exists()
    assert "pwned" not in slave.read_text()


def test_unused_entries_and_old_leftovers_are_pruned_when_a_new_one_is_unpacked(cache, tmp_path):
    old = make_archive(tmp_path / "old.fmu", FILES)
    recent = make_archive(tmp_path / "recent.fmu", {**FILES, "resources/x.py": "X = 2\n"})
    old_dest, recent_dest = extract_cached(old), extract_cached(recent)
    leftover = cache / ".fmu-partial-killed"
    leftover.mkdir()
    month_ago = os.stat(old_dest / MANIFEST).st_mtime - fmucache.MAX_AGE - 60
    os.utime(old_dest / MANIFEST, (month_ago, month_ago))
    os.utime(leftover, (month_ago, month_ago))
    fmucache._VERIFIED.clear()
    extract_cached(make_archive(tmp_path / "new.fmu", {**FILES, "resources/x.py": "X = 3\n"}))
    assert not old_dest.exists() and not leftover.exists()
    assert recent_dest.is_dir()
    assert leftovers(cache) == []
