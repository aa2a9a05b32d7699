"""The README's library snippets run as written, in a fresh folder, and leave nothing in
the repository."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def library_snippets() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text[text.index("### Library"):text.index("## Your own spacecraft")]
    return re.findall(r"```python\n(.*?)```", section, re.S)


def test_the_readme_has_its_two_library_snippets():
    snippets = library_snippets()
    assert len(snippets) == 2
    for code in snippets:   # every imported name is used (no stale import)
        for line in code.splitlines():
            m = re.match(r"from \S+ import (.+)", line)
            if m:
                for name in (n.strip() for n in m.group(1).split(",")):
                    uses = re.findall(rf"\b{re.escape(name)}\b", code)
                    assert len(uses) >= 2, f"{name} is imported but not used"


@pytest.mark.slow
def test_the_library_snippets_run_in_a_fresh_folder(tmp_path, suite_fmus):
    fmus = suite_fmus("truss10_structure", "piezo_p243_40", "piezo_p243_30",
                      "controller_truss10_strain_diag", "controller_truss10_strain_long",
                      "excitation")
    folder = next(iter(fmus.values())).parent
    shutil.copytree(ROOT / "scenarios", tmp_path / "scenarios")
    os.symlink(folder, tmp_path / "fmus")
    before = set(p.name for p in ROOT.iterdir())
    for i, code in enumerate(library_snippets()):
        script = tmp_path / f"snippet{i}.py"
        script.write_text(code, encoding="utf-8")
        proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path,
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "out/truss10.npz").is_file()
    assert (tmp_path / "out/run/results.parquet").is_file()
    assert set(p.name for p in ROOT.iterdir()) == before
