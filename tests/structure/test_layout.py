"""The package's shape, as the architecture promises it: small functions, one job per package, said in its
docstring."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import edc_bench

PACKAGE = Path(edc_bench.__file__).parent
#: The longest a function may be, docstring aside: past it, it does more than one thing.
MAX_FUNCTION_LINES = 80


def _long_functions(source: str) -> list[tuple[str, int]]:
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            doc = body[0] if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                else None
            lines = node.end_lineno - node.lineno + 1 - ((doc.end_lineno - doc.lineno + 1) if doc else 0)
            if lines > MAX_FUNCTION_LINES:
                out.append((node.name, lines))
    return out


def test_no_function_is_longer_than_80_lines() -> None:
    found = {path.relative_to(PACKAGE).as_posix(): long
             for path in sorted(PACKAGE.rglob("*.py")) if (long := _long_functions(path.read_text(encoding="utf-8")))}
    assert found == {}


def test_the_length_check_sees_a_long_function() -> None:
    source = "def f():\n    '''doc'''\n" + "    x = 1\n" * 81
    assert _long_functions(source) == [("f", 82)]  # the def line and 81 of body, the docstring aside


def test_every_package_says_its_one_job() -> None:
    packages = sorted(p.parent for p in PACKAGE.rglob("__init__.py"))
    for folder in packages:
        name = ".".join(folder.relative_to(PACKAGE.parent).parts)
        doc = importlib.import_module(name).__doc__
        assert doc and len(doc.strip()) > 40, name
