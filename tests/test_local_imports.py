"""Imports sit at the top of their module; one inside a function says why on the line above it
(or above its group of imports): its measured start-up cost (tests/cli/test_startup.py). A
``try`` around it (probing an optional dependency) says why by itself."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "pipeline"


def unexplained_local_imports(source: str) -> list[int]:
    """Lines of the imports inside a function of ``source`` with no comment on the line above
    their group of consecutive imports and no ``try`` around them."""
    lines = source.splitlines()
    found = []

    def visit(node, in_function: bool, in_try: bool) -> None:
        for field in ("body", "orelse", "finalbody", "handlers"):
            statements = getattr(node, field, [])
            if not isinstance(statements, list):
                continue
            for before, statement in zip([None] + statements, statements):
                grouped = isinstance(before, (ast.Import, ast.ImportFrom))
                if isinstance(statement, (ast.Import, ast.ImportFrom)) and in_function and not in_try \
                        and not grouped and not lines[statement.lineno - 2].lstrip().startswith("#"):
                    found.append(statement.lineno)
        for child in ast.iter_child_nodes(node):
            visit(child, in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)),
                  in_try or isinstance(child, ast.Try))

    visit(ast.parse(source), False, False)
    return found


def test_every_import_inside_a_function_says_why():
    unexplained = [f"{path.relative_to(PACKAGE.parent)}:{line}" for path in sorted(PACKAGE.rglob("*.py"))
                   for line in unexplained_local_imports(path.read_text())]
    assert unexplained == [], "move these imports to the module's top, or say why not:\n" + "\n".join(unexplained)


def test_an_unexplained_local_import_is_found():
    source = ("import os\n\n\ndef f():\n    x = 1\n    import json\n    return json, x, os\n\n\n"
              "def g():\n    # imported here, not at the top: ≈0.3 CPU-s\n    import json\n    import csv\n"
              "    try:\n        import cryptography\n    except ImportError:\n        pass\n    return json, csv\n")
    assert unexplained_local_imports(source) == [6]
