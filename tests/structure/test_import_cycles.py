"""No two modules import each other, however the import is hidden: a function-level import that breaks a cycle at
load time still couples the two modules both ways (#54: control/law and pid, physics/coil and valve were two).
Imports for type hints only (``if TYPE_CHECKING:``) do not count: they run under a type checker, never here."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "edc_bench"


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(tree: ast.AST, known: set[str]) -> set[str]:
    """The package's modules that ``tree`` imports anywhere (functions too), type-checking blocks aside."""
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.update(t for t in (node.module, *(f"{node.module}.{a.name}" for a in node.names)) if t in known)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name in known)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return found


def import_cycles(sources: dict[str, str]) -> list[list[str]]:
    """The groups of modules that import one another (strongly connected, two or more), from module -> source."""
    known = set(sources)
    graph = {name: _imports(ast.parse(text), known) - {name} for name, text in sources.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def connect(node: str) -> None:  # Tarjan's algorithm
        index[node] = low[node] = len(index)
        stack.append(node)
        for other in graph[node]:
            if other not in index:
                connect(other)
                low[node] = min(low[node], low[other])
            elif other in stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            group = []
            while True:
                member = stack.pop()
                group.append(member)
                if member == node:
                    break
            if len(group) > 1:
                cycles.append(sorted(group))

    for name in sorted(graph):
        if name not in index:
            connect(name)
    return cycles


def test_no_two_modules_of_the_package_import_each_other() -> None:
    sources = {_module_name(p): p.read_text(encoding="utf-8") for p in sorted(PACKAGE.rglob("*.py"))}
    assert import_cycles(sources) == []


def test_the_check_sees_a_cycle_hidden_in_a_function_and_not_one_for_type_hints() -> None:
    hidden = {"p.law": "def of():\n    from p.pid import f\n", "p.pid": "from p import law\nfrom p.law import g\n"}
    assert import_cycles(hidden) == [["p.law", "p.pid"]]
    typed = {"p.fel": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from p.design import D\n",
             "p.design": "from p.fel import F\n"}
    assert import_cycles(typed) == []
