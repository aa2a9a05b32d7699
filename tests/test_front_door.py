"""The front door's walk through the pipeline (``orchestrator.__doc__``) runs as written,
and every script under ``examples/`` runs to its end (each checks its own golden value)."""

from __future__ import annotations

import doctest
import os
import subprocess
import sys
from pathlib import Path

import pytest

import orchestrator

ROOT = Path(__file__).resolve().parents[1]
TEN_BAY = ("truss10_structure", "piezo_p243_40", "piezo_p243_30",
           "controller_truss10_strain_diag", "controller_truss10_strain_long", "excitation")


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::orchestrator.cosim.UnconnectedInputWarning")
def test_the_front_door_docstring_runs(suite_fmus, suite_fmu_dir, monkeypatch):
    suite_fmus(*TEN_BAY)
    monkeypatch.chdir(ROOT)
    finder = doctest.DocTestFinder(recurse=False)
    (test,) = finder.find(orchestrator, "orchestrator", globs={"fmu_dir": suite_fmu_dir})
    assert len(test.examples) >= 5
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    result = runner.run(test)
    assert result.failed == 0


#: Examples with a test file of their own (tests/test_<name>.py), run there with short runs.
OWN_TESTS = {p.name for p in (ROOT / "examples").glob("*.py")
             if (ROOT / "tests" / f"test_{p.stem}.py").is_file()}


@pytest.mark.slow
@pytest.mark.parametrize("script", sorted(p.name for p in (ROOT / "examples").glob("*.py")
                                          if p.name not in OWN_TESTS))
def test_example_runs(script, tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, str(ROOT / "examples" / script),
                           "--out", str(tmp_path / "out"), "--workers", "0"],
                          capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "golden value" in proc.stdout
