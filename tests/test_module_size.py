"""No orchestrator module passes 600 lines (the linear-engine issue's rule: an experiment
reads as a short script of calls, and a module that grows past it is split by what it
does, as the Monte Carlo's results and the campaign file's uncertainty table were)."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LIMIT = 600


def test_no_orchestrator_module_passes_600_lines():
    sizes = {p.relative_to(ROOT).as_posix(): len(p.read_text(encoding="utf-8").splitlines())
             for p in (ROOT / "orchestrator").rglob("*.py")}
    assert len(sizes) > 20   # the package was found
    over = {p: n for p, n in sizes.items() if n > LIMIT}
    assert not over, f"modules over {LIMIT} lines: {over}"
