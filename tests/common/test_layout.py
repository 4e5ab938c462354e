"""The house by role: imports point one way, modules stay small."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: package -> packages of ours it may import (the layers below it)
ALLOWED = {
    "adcs_common": set(),
    "allocation": {"adcs_common"},
    "thrusters": {"adcs_common"},
    "ocp": {"adcs_common", "allocation", "thrusters"},
    "adcs": {"adcs_common", "allocation", "thrusters", "ocp"},
}


def _imported_packages(path: Path) -> set[str]:
    """Top-level packages of ours that a module imports (anywhere in it)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            names = [node.module or ""]
        else:
            continue
        found |= {n.split(".")[0] for n in names} & set(ALLOWED)
    return found


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_imports_point_one_way(package):
    wrong = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        bad = _imported_packages(path) - ALLOWED[package] - {package}
        if bad:
            wrong[str(path.relative_to(ROOT))] = sorted(bad)
    assert not wrong, f"imports against the layering: {wrong}"


def test_the_layering_test_sees_a_violation(tmp_path):
    bad = tmp_path / "m.py"
    bad.write_text("def f():\n    from ocp.models import rigid\n")
    assert _imported_packages(bad) == {"ocp"}


def _code_lines(src: list[str], node: ast.AST) -> int:
    body = node.body
    first = body[0]
    start = (first.end_lineno + 1 if isinstance(first, ast.Expr)
             and isinstance(first.value, ast.Constant)
             and isinstance(first.value.value, str) else first.lineno)
    return sum(1 for line in src[start - 1:node.end_lineno]
               if line.strip() and not line.strip().startswith("#"))


def test_modules_and_functions_stay_small():
    too_long, big_functions = {}, {}
    for package in ALLOWED:
        for path in sorted((ROOT / package).rglob("*.py")):
            text = path.read_text()
            name = str(path.relative_to(ROOT))
            if text.count("\n") > 600:
                too_long[name] = text.count("\n")
            src = text.splitlines()
            for node in ast.walk(ast.parse(text)):
                if isinstance(node, (ast.FunctionDef,
                                     ast.AsyncFunctionDef)):
                    n = _code_lines(src, node)
                    if n > 80:
                        big_functions[f"{name}:{node.name}"] = n
    assert not too_long, f"modules over 600 lines: {too_long}"
    assert not big_functions, f"functions over 80 lines: {big_functions}"
