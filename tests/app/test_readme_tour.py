"""The README's Python tour runs, and its comments' numbers are true.

Every ```python block of README.md is executed in order, statement by
statement, in one namespace. A bare expression whose line ends with a
comment starting with a number (``x  # 6.5210 N·m·s``) is evaluated and
compared with that number to the digits it shows (half a unit of its
last digit); for a tuple, its first element. A second number after a
comma compares with the tuple's second element when that is a number,
and a word with its text.
"""

import ast
import math
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
NUMBER = r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?"
CLAIM = re.compile(rf"#\s*({NUMBER})\b[^,]*(?:,\s*(\S+))?")


def _blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```",
                      (ROOT / "README.md").read_text(), re.S)


def _close(value: float, shown: str) -> bool:
    """``value`` rounds to ``shown`` (half a unit of its last digit)."""
    digits = len(shown.split(".")[1]) if "." in shown else 0
    return math.isclose(value, float(shown), rel_tol=0,
                        abs_tol=0.5 * 10.0 ** -digits + 1e-12)


def _claims(source: str) -> dict[int, tuple[str, str | None]]:
    """Line number -> (number, second item) of the commented claims."""
    found = {}
    for no, line in enumerate(source.splitlines(), 1):
        code, hash_, comment = line.partition("#")
        m = CLAIM.match(hash_ + comment) if hash_ else None
        if m and code.strip():
            found[no] = (m[1], m[2])
    return found


def _check(value, number: str, second: str | None, where: str) -> None:
    items = value if isinstance(value, tuple) else (value,)
    assert _close(float(items[0]), number), (where, items[0], number)
    if second is not None and len(items) > 1:
        if re.fullmatch(NUMBER, second):
            assert _close(float(items[1]), second), (where, items[1])
        else:
            assert str(items[1]) == second.strip("'\""), (where, items[1])


def test_the_readme_has_a_tour_with_claims():
    claims = [c for b in _blocks() for c in _claims(b).values()]
    assert len(_blocks()) >= 1 and len(claims) >= 2


@pytest.mark.slow
def test_the_readme_tour_runs_and_its_numbers_hold():
    namespace: dict = {"__name__": "readme_tour"}
    checked = 0
    for k, block in enumerate(_blocks()):
        claims = _claims(block)
        for stmt in ast.parse(block).body:
            where = f"README python block {k + 1}, line {stmt.lineno}"
            if isinstance(stmt, ast.Expr) and stmt.lineno in claims:
                value = eval(compile(ast.Expression(stmt.value), where,
                                     "eval"), namespace)
                _check(value, *claims[stmt.lineno], where)
                checked += 1
            else:
                exec(compile(ast.Module([stmt], []), where, "exec"),
                     namespace)
    assert checked >= 2


def test_a_wrong_comment_is_caught():
    claims = _claims("x = 1\nx * 6.5210  # 1.6303 (H* = 1)\n")
    assert claims == {2: ("1.6303", None)}
    with pytest.raises(AssertionError):
        _check(6.5210, "1.6303", None, "here")
    _check((201.6884, "Solve_Succeeded"), "201.69", "Solve_Succeeded",
           "here")
    assert _close(6.521011, "6.5210") and not _close(6.5216, "6.5210")
