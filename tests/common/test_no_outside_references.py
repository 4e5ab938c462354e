"""The repository cites its sources itself: no file points outside it."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SUFFIXES = {".py", ".md", ".ipynb", ".toml", ".cff", ".c", ".in", ".txt",
            ".cfg", ".yml", ".yaml", ".j2", ".html", ".rst"}
SKIP = {".git", ".venv", "venv", "build", "dist", "__pycache__",
        "adcs-report", "sweeps"}
#: the team's notes and the source files of the papers live outside the
#: repository: users have docs/references.md, docs/theory.md, docs/errata.md
OUTSIDE = re.compile("|".join([
    r"\.\./" + "shared",
    r"\b" + "SP" + r"EC\b",
    "[Ss]eeds? " + r"0\d\d",
    "seed_" + r"0\d\d",
    "seed-" + r"0\d\d",
    r"\bthe " + "seed" + r"\b",
    "seed" + r"'s\b",
]))


def text_files():
    for path in ROOT.rglob("*"):
        parts = set(path.relative_to(ROOT).parts)
        # virtual environments (.venv-ci, venv, ...), caches, build output
        if parts & SKIP or any(p.endswith(".egg-info") or p.startswith(".")
                               or "venv" in p or p == "site-packages"
                               for p in parts):
            continue
        if path.is_file() and path.suffix in SUFFIXES:
            yield path


def test_no_file_refers_to_notes_or_sources_outside_the_repository():
    hits = []
    for path in text_files():
        for i, line in enumerate(path.read_text(errors="ignore")
                                 .splitlines(), 1):
            if OUTSIDE.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{i}: {line.strip()}")
    assert not hits, "\n".join(hits[:20])


def test_the_citations_resolve_to_the_docs():
    refs = (ROOT / "docs" / "references.md").read_text()
    for n in range(1, 5):
        assert f"**[{n}]**" in refs
    theory = (ROOT / "docs" / "theory.md").read_text()
    for section in ("## 1.", "### 1.2", "### 1.3", "## 2.", "## 3.",
                    "## 4."):
        assert section in theory
    assert "docs/references.md" in (ROOT / "README.md").read_text()
