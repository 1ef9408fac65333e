"""Every relative link and picture in the README and docs/**/*.md points at a file that exists (and, with #anchor, at
a heading of that file), so moving text between pages cannot leave a dead link behind; every page is reachable from
the README through the guide's index (docs/README.md) or the notes' (docs/notes/README.md)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
CODE = re.compile(r"```.*?```|`[^`\n]*`", re.S)


def heading_anchors(page: Path) -> set[str]:
    """GitHub's anchors of a page's headings: lower case, punctuation dropped, spaces as hyphens."""
    text = CODE.sub("", page.read_text(encoding="utf-8"))
    titles = re.findall(r"^#+\s+(.+?)\s*$", text, re.M)
    return {re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-") for title in titles}


def relative_links(page: Path) -> list[str]:
    """The targets of the page's links and pictures outside code, web addresses left out."""
    text = CODE.sub("", page.read_text(encoding="utf-8"))
    return [t for t in LINK.findall(text) if not re.match(r"[a-z]+:", t)]


def test_anchors_follow_github_rules():
    assert heading_anchors(ROOT / "README.md") >= {"what-it-costs", "command-line"}
    assert "weights-offline" in heading_anchors(ROOT / "docs" / "setup.md")  # parentheses dropped
    assert "the-studios-sliders" in heading_anchors(ROOT / "docs" / "notes" / "artist-controls.md")  # apostrophe


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_links_resolve(page: Path):
    broken = []
    for target in relative_links(page):
        path, _, anchor = target.partition("#")
        file = (page.parent / path).resolve() if path else page
        if not file.exists():
            broken.append(target)
        elif anchor and anchor not in heading_anchors(file):
            broken.append(target)
    assert not broken, f"{page.name}: dead links {broken}"


def linked_pages(page: Path) -> set[Path]:
    """The files ``page`` links to, resolved."""
    return {(page.parent / t.partition("#")[0]).resolve() for t in relative_links(page) if t.partition("#")[0]}


def test_every_docs_page_is_reachable_from_the_readme():
    readme, guide, notes = ROOT / "README.md", ROOT / "docs" / "README.md", ROOT / "docs" / "notes" / "README.md"
    assert {guide.resolve(), notes.resolve()} <= linked_pages(readme)
    unlinked_guide = [p.name for p in sorted((ROOT / "docs").glob("*.md")) if p != guide
                      and p.resolve() not in linked_pages(guide)]
    unlinked_notes = [p.name for p in sorted((ROOT / "docs" / "notes").glob("*.md")) if p != notes
                      and p.resolve() not in linked_pages(notes)]
    assert (unlinked_guide, unlinked_notes) == ([], [])


def test_the_readme_reads_in_one_sitting():
    """A newcomer's first page: under 150 lines, its two commands first."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) < 150
    first_block = text.partition("```bash\n")[2].partition("```")[0].splitlines()
    assert first_block == ["bash scripts/setup.sh && .venv/bin/gstyle-studio", "bash scripts/test.sh"]
