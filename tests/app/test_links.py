"""Every relative link of the Markdown and the notebooks resolves.

README.md, docs/*.md and the notebooks' Markdown cells: a link to a file
names one that exists (from the linking file's folder), and a link with
an anchor names a heading of its target (the slug of GitHub and of the
docs build, ``myst_heading_anchors``). External links (``https:``,
``mailto:``) are not fetched.
"""

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

#: a Markdown link or image ``[text](target)`` (the text may hold one
#: level of brackets: ``[[1]](references.md)``) and a reference definition
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]"
                  r"\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)"
                  r"|^\s*\[[^\]]+\]:\s*(\S+)", re.M)
FENCE = re.compile(r"^(```|~~~).*?^\1", re.M | re.S)
CODE = re.compile(r"`[^`\n]*`")
HEADING = re.compile(r"^#{1,6}\s+(.*?)\s*#*\s*$", re.M)


def _markdown(path: Path) -> str:
    """The Markdown of a page, or of a notebook's Markdown cells."""
    if path.suffix == ".ipynb":
        cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
        return "\n\n".join("".join(c["source"]) for c in cells
                           if c["cell_type"] == "markdown")
    return path.read_text(encoding="utf-8")


def _prose(text: str) -> str:
    """``text`` without code blocks and code spans (no links there)."""
    return CODE.sub("", FENCE.sub("", text))


def slug(heading: str) -> str:
    """A heading's anchor: its text (links' text, no code marks),
    lowercased, without punctuation but ``-`` and ``_``, spaces to ``-``
    (GitHub's and MyST's rule)."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    text = re.sub(r"[^\w\- ]", "", text.strip().lower())
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """The heading anchors of a page or notebook."""
    return {slug(h) for h in HEADING.findall(FENCE.sub("", _markdown(path)))}


def links(path: Path) -> list[str]:
    """The relative links of a page or notebook (external ones left)."""
    found = [a or b for a, b in LINK.findall(_prose(_markdown(path)))]
    return [t for t in found
            if not re.match(r"^[a-z][a-z0-9+.-]*:", t, re.I)]


def broken(path: Path) -> list[str]:
    """The links of ``path`` that do not resolve, each with the reason."""
    bad = []
    for target in links(path):
        file, _, anchor = target.partition("#")
        dest = (path.parent / file).resolve() if file else path
        if not dest.exists():
            bad.append(f"{target}: no file {dest}")
        elif anchor and dest.suffix in (".md", ".ipynb") and (
                anchor not in anchors(dest)):
            bad.append(f"{target}: no heading #{anchor} in {dest.name}")
    return bad


FILES = ([ROOT / "README.md", ROOT / "CHANGELOG.md"]
         + sorted((ROOT / "docs").glob("*.md"))
         + sorted((ROOT / "notebooks").glob("*.ipynb")))


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_every_relative_link_resolves(path):
    assert broken(path) == []


def test_the_pages_link_to_each_other():
    """The check sees the links: README and the notebooks point into the
    docs, the notebooks to the references."""
    readme = links(ROOT / "README.md")
    assert "docs/errata.md" in readme and "docs/guide.md" in readme
    assert "../docs/references.md" in links(
        ROOT / "notebooks" / "00_quickstart.ipynb")
    assert "errata.md" in links(ROOT / "docs" / "findings.md")


def test_the_check_catches_a_dead_link_and_a_dead_anchor(tmp_path):
    (tmp_path / "a.md").write_text(
        "# Title here\n\n## The `code` part\n\nSee [b](b.md), [it](#title-"
        "here), [code](#the-code-part), [gone](#nowhere), [up](../errata.md)"
        " and `[not](a-link.md)`.\n\n```\n[nor](this.md)\n```\n")
    (tmp_path / "b.md").write_text("# B\n")
    assert broken(tmp_path / "a.md") == [
        "#nowhere: no heading #nowhere in a.md",
        f"../errata.md: no file {(tmp_path.parent / 'errata.md')}"]
    assert slug("δ/γ trade of the [Meteor-M](x.md) pyramid") == (
        "δγ-trade-of-the-meteor-m-pyramid")
