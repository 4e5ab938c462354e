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
