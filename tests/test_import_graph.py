"""The project's modules import one another without cycles.

Every ``import`` and ``from ... import`` statement of the project's own packages (at
module level or inside a function: a cycle hidden in a function is still a cycle) is
read with :mod:`ast`, resolved to the module it names, and the resulting graph is
checked for strongly connected components of more than one module.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from orchestrator.cosim.graph import strongly_connected

ROOT = Path(__file__).resolve().parents[1]
PACKAGE_ROOTS = [ROOT / "src", ROOT]
PACKAGES = sorted({p.parent.name for base in PACKAGE_ROOTS for p in base.glob("*/__init__.py")
                   if p.parent.name not in ("tests", "benchmarks", "examples")})


def project_modules() -> dict:
    """``{dotted name: file}`` of every module of the project's packages."""
    out = {}
    for base in PACKAGE_ROOTS:
        for pkg in PACKAGES:
            root = base / pkg
            if not (root / "__init__.py").is_file():
                continue
            for f in root.rglob("*.py"):
                if "__pycache__" in f.parts:
                    continue
                parts = list(f.relative_to(base).with_suffix("").parts)
                if parts[-1] == "__init__":
                    parts = parts[:-1]
                out[".".join(parts)] = f
    return out


def imports_of(name: str, path: Path, modules: dict) -> set:
    """Project modules that ``name`` (file ``path``) imports anywhere in its code."""
    is_pkg = path.name == "__init__.py"
    package = name if is_pkg else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            # `from pkg import sub` imports the submodule pkg.sub when there is one
            targets = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in modules else mod
                       for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in modules:   # `import a.b.c` -> the deepest project module
                t = t.rpartition(".")[0]
            if t and t != name:
                found.add(t)
    return found


def cycles(graph: dict) -> list:
    """Strongly connected components with more than one node, each sorted."""
    nodes = sorted(graph)
    edges = [(a, b) for a in nodes for b in sorted(graph[a]) if b in graph]
    return sorted(sorted(c) for c in strongly_connected(nodes, edges) if len(c) > 1)


def test_the_checker_finds_a_cycle_and_accepts_a_chain():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": {"a"}, "c": {"d"}, "d": {"c"}}) == [["a", "b"], ["c", "d"]]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_relative_imports_resolve_to_project_modules(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    for f in ("__init__.py", "a.py", "sub/__init__.py", "sub/b.py"):
        (pkg / f).write_text("")
    (pkg / "sub" / "b.py").write_text("from ..a import x\nfrom . import c\n"
                                      "def f():\n    import pkg.sub\n")
    modules = {"pkg": pkg / "__init__.py", "pkg.a": pkg / "a.py",
               "pkg.sub": pkg / "sub/__init__.py", "pkg.sub.b": pkg / "sub/b.py"}
    assert imports_of("pkg.sub.b", pkg / "sub/b.py", modules) == {"pkg.a", "pkg.sub"}


def test_no_import_cycle_among_the_projects_modules():
    modules = project_modules()
    assert "orchestrator.cosim.simulation" in modules and "structfmu" in modules
    graph = {name: imports_of(name, path, modules) for name, path in modules.items()}
    found = cycles(graph)
    if found:
        pytest.fail("import cycles: " + "; ".join(" <-> ".join(c) for c in found))
