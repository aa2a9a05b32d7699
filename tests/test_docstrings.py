"""Every public function or method of two or more parameters documents them (numpydoc
``Parameters`` section), in the project's packages."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def undocumented(path: Path) -> list[str]:
    """Public functions of ``path`` with two or more parameters and no Parameters section."""
    out = []

    def visit(nodes, owner=""):
        for node in nodes:
            if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                visit(node.body, f"{node.name}.")
            elif isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
                args = [a.arg for a in node.args.args + node.args.kwonlyargs
                        if a.arg not in ("self", "cls")]
                args += ["*args"] if node.args.vararg else []
                if len(args) >= 2 and "Parameters" not in (ast.get_docstring(node) or ""):
                    out.append(f"{owner}{node.name}")

    visit(ast.parse(path.read_text(encoding="utf-8")).body)
    return out


def test_the_checker_sees_a_missing_section(tmp_path):
    f = tmp_path / "m.py"
    f.write_text('def ok(a):\n    pass\n\ndef bad(a, b):\n    """No section."""\n\n'
                 'class C:\n    def m(self, a, b):\n        """Parameters\n    ----------"""\n'
                 '    def n(self, a, *rest):\n        pass\n\ndef _private(a, b):\n    pass\n')
    assert undocumented(f) == ["bad", "C.n"]


def test_public_functions_document_their_parameters():
    missing = [f"{p.relative_to(ROOT)}: {name}"
               for base in (ROOT / "src", ROOT / "orchestrator")
               for p in sorted(base.rglob("*.py")) if "__pycache__" not in p.parts
               for name in undocumented(p)]
    assert not missing, "\n".join(missing)
