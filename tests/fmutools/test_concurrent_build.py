"""Two builds into one folder at once both succeed and leave whole FMUs."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.long   # make test-full: two builds at once, 10 s
@pytest.mark.slow
def test_two_builds_into_one_folder_at_once_both_succeed(tmp_path):
    # Each build holds every archive it writes open for 1.5 s before closing it, so the
    # two builds are writing the same FMUs at the same time (as two `jitterfmu build
    # --out D` of the whole suite are), however the machine schedules them.
    script = textwrap.dedent(f"""
        import sys, time, zipfile
        close = zipfile.ZipFile.close
        def slow_close(self):
            if self.mode == "w" and self.fp is not None:
                time.sleep(1.5)
            close(self)
        zipfile.ZipFile.close = slow_close
        from orchestrator.cli import main
        sys.exit(main(["build", "--model", "excitation", "--out", {str(tmp_path)!r}]))
    """)
    procs = [subprocess.Popen([sys.executable, "-c", script], cwd=ROOT, text=True,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE)
             for _ in range(2)]
    results = [p.communicate(timeout=300) for p in procs]
    for p, (out, err) in zip(procs, results):
        assert p.returncode == 0, err[-2000:]
    for fmu in (tmp_path / "excitation.fmu", tmp_path / "python" / "excitation.fmu"):
        with zipfile.ZipFile(fmu) as z:
            assert z.testzip() is None
            assert "modelDescription.xml" in z.namelist()
    leftovers = [p.name for p in tmp_path.rglob("*") if p.is_file()
                 and p.suffix not in (".fmu",) and p.name not in (".sources", ".lock")]
    assert leftovers == []
