"""The versions Basilisk pins are the ones docs/basilisk.md tables.

#26: the README's first command installs ``.[solvers,basilisk]`` so that
``adcs report`` runs the Basilisk study (the README's headline); the
``bsk`` package caps matplotlib, pandas, pillow, tqdm and numpy. The
table holds what ``pyproject.toml`` and ``bsk``'s metadata say, and what
a fresh install resolves.
"""

import re
from importlib import metadata
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

import pytest
from packaging.requirements import Requirement
from packaging.specifiers import SpecifierSet
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[2]
PINNED = ("matplotlib", "pandas", "pillow", "tqdm", "numpy")


def _table() -> tuple[list[str], dict[str, list[str]]]:
    """Header and rows (by package) of 'The versions Basilisk pins'."""
    text = (ROOT / "docs" / "basilisk.md").read_text(encoding="utf-8")
    section = text.split("## The versions Basilisk pins", 1)[1]
    section = section.split("\n## ", 1)[0]
    lines = [ln for ln in section.splitlines() if ln.startswith("|")]
    cells = [[c.strip() for c in ln.strip("|").split("|")] for ln in lines]
    header, rows = cells[0], cells[2:]
    return header, {r[0]: r for r in rows}


def _specs(cell: str) -> list[SpecifierSet]:
    """The code spans of a cell, each a specifier set."""
    return [SpecifierSet(s) for s in re.findall(r"`([^`]*)`", cell)]


def _pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def _bsk_requires() -> dict[str, list[Requirement]]:
    """bsk's install requirements (no extras), by package name."""
    out: dict[str, list[Requirement]] = {}
    for text in metadata.requires("bsk") or []:
        req = Requirement(text)
        if req.marker is not None and "extra" in str(req.marker):
            continue
        out.setdefault(req.name.lower(), []).append(req)
    return out


def _bsk_version() -> str | None:
    try:
        return metadata.version("bsk")
    except metadata.PackageNotFoundError:
        return None


def test_the_table_lists_every_pinned_package():
    header, rows = _table()
    assert header == ["package", "adcs-toolbox requires",
                      "bsk 2.12.1 requires", "`.[solvers]` resolves",
                      "`.[solvers,basilisk]` resolves"]
    assert sorted(rows) == sorted(PINNED)


def test_the_toolbox_column_is_pyproject():
    deps = {Requirement(d).name.lower(): Requirement(d).specifier
            for d in _pyproject()["dependencies"]}
    _, rows = _table()
    for name in PINNED:
        ours = _specs(rows[name][1])
        if name in deps:
            assert ours == [deps[name]], name
        else:                     # pillow: matplotlib's dependency
            assert ours == [] and "matplotlib" in rows[name][1], name
    assert _pyproject()["optional-dependencies"]["basilisk"] == [
        "bsk>=2.12,<2.13"]


def test_the_documented_resolutions_meet_the_documented_ranges():
    _, rows = _table()
    for name in PINNED:
        plain, capped = (Version(rows[name][k]) for k in (3, 4))
        bsk = _specs(rows[name][2])
        assert bsk, name
        assert capped in bsk[0], (name, capped)      # Python < 3.13 range
        assert all(capped in s for s in _specs(rows[name][1]))
        assert plain >= capped, name                 # the cap only lowers
    # the four the issue saw downgraded are lower with Basilisk
    assert all(Version(rows[n][3]) > Version(rows[n][4])
               for n in ("matplotlib", "pandas", "pillow", "tqdm"))


@pytest.mark.skipif(_bsk_version() is None,
                    reason="Basilisk is not installed (the basilisk extra)")
def test_the_bsk_column_is_bsks_metadata_and_holds_here():
    assert _bsk_version() == "2.12.1", (
        f"bsk {_bsk_version()} is installed: update the table of "
        "docs/basilisk.md (its header names 2.12.1)")
    _, rows = _table()
    reqs = _bsk_requires()
    for name in PINNED:
        documented = _specs(rows[name][2])
        declared = reqs[name]
        assert sorted(map(str, documented)) == sorted(
            str(r.specifier) for r in declared), name
        here = [r for r in declared
                if r.marker is None or r.marker.evaluate()]
        assert len(here) == 1, name
        installed = Version(metadata.version(name))
        assert installed in here[0].specifier, (name, installed)
        # a fresh install resolves each to its documented version
        assert installed == Version(rows[name][4]), (name, installed)


def test_the_readme_installs_what_the_report_needs():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    first = 'pip install -e ".[solvers,basilisk]" && adcs report'
    assert first in readme
    assert "docs/basilisk.md#the-versions-basilisk-pins" in readme
    # CI's install holds every extra of the first command
    ci = (ROOT / ".ci" / "run").read_text()
    extras = re.search(r'pip install -e "\.\[([^\]]*)\]"', ci).group(1)
    assert {"solvers", "basilisk"} <= set(extras.split(","))


def test_without_basilisk_the_study_says_why_in_one_line(monkeypatch,
                                                         tmp_path):
    import adcs.studies.basilisk as study
    from adcs.report import StudyContext

    monkeypatch.setattr(study, "basilisk_available", lambda: False)
    section = study.run(StudyContext(out=tmp_path, quick=True))
    assert section.summary == [
        'skipped: Basilisk not installed; pip install -e ".[basilisk]" (the '
        "bsk package, Basilisk 2.12; about 75 MB)"]
    assert not section.tables and not section.figures
    assert "docs/basilisk.md" in section.intro
