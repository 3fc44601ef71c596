"""How much of the package still passes data as untyped mappings (#54): counted, printed, and never more.

The issue's measure: ``dict[str, Any]`` annotations and subscripts by a string key (``x["verdict"]``). A record
concept held as a typed model has neither; each one converted lowers the ceiling below, which a change may only
lower further (a new untyped mapping fails here, saying where the counts stand).
"""

from __future__ import annotations

import ast
from pathlib import Path

import edc_bench

#: The counts as of the last change that lowered them, as :func:`counts` counts them (every occurrence, every
#: subscript by a string constant: #54's first figures, 146 and about 300, counted lines with grep), set 2026-11-29 (subscripts 248 on 2026-12-02: the station's settings written from one mapping).
CEILING = {"dict[str, Any] annotations": 81, "string-key subscripts": 248}


def counts() -> dict[str, int]:
    """The package's ``dict[str, Any]`` annotations and string-key subscripts, in its source files."""
    annotations = subscripts = 0
    for path in Path(edc_bench.__file__).parent.rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        annotations += text.count("dict[str, Any]")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) \
                    and isinstance(node.slice.value, str) and node.slice.value.isidentifier():
                subscripts += 1
    return {"dict[str, Any] annotations": annotations, "string-key subscripts": subscripts}


def test_untyped_mappings_are_counted_and_do_not_grow() -> None:
    found = counts()
    print(f"\n#54: {found} (ceiling {CEILING})")
    for name, count in found.items():
        assert count <= CEILING[name], (f"{count} {name} in edc_bench, more than the {CEILING[name]} before this "
                                        "change: give the new data a typed model (see records/schema.py)")
