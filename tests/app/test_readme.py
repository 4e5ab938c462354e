"""The README's commands are the ones CI runs."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_ci_runs_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    test_cmd = ('pip install -e '
                '".[test,solvers,notebooks,sweep,basilisk,docs]"'
                ' && python -m pytest -q -n auto --dist loadfile')
    assert test_cmd in readme
    assert test_cmd in ci
