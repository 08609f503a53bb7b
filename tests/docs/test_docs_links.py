"""The README and docs/ stand alone: every relative link resolves to a file of the repository, every
``#anchor`` to a heading of its page, and no link leaves the repository through a relative path."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PAGES = sorted([REPO / "README.md", *(REPO / "docs").rglob("*.md")])
_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
_CODE = re.compile(r"```.*?```|`[^`\n]*`", re.S)
_FENCED = re.compile(r"```.*?```", re.S)


def _anchors(page: Path) -> set[str]:
    """GitHub's anchors of a page's headings: lower case, punctuation (and code's backticks) dropped,
    spaces to '-'."""
    found = set()
    for line in _FENCED.sub("", page.read_text(encoding="utf-8")).splitlines():
        if line.startswith("#"):
            title = line.lstrip("#").strip().lower()
            found.add(re.sub(r"[^\w\- ]", "", title).replace(" ", "-"))
    return found


def links_of(page: Path) -> list[str]:
    return _LINK.findall(_CODE.sub("", page.read_text(encoding="utf-8")))


def test_every_relative_link_resolves_inside_the_repository() -> None:
    wrong = []
    for page in PAGES:
        for link in links_of(page):
            if re.match(r"[a-z]+:", link):          # https:, mailto:
                continue
            target, _, anchor = link.partition("#")
            path = (page.parent / target).resolve() if target else page
            where = f"{page.relative_to(REPO)}: {link}"
            if not path.is_relative_to(REPO):
                wrong.append(f"{where}: outside the repository")
            elif not path.exists():
                wrong.append(f"{where}: no such file")
            elif anchor and path.suffix == ".md" and anchor not in _anchors(path):
                wrong.append(f"{where}: no heading #{anchor} in {path.relative_to(REPO)}")
    assert wrong == []


def test_the_pages_link_to_each_other() -> None:
    """Every page of docs/ is reachable from the README, directly or through other pages."""
    reached = {REPO / "README.md"}
    todo = [REPO / "README.md"]
    while todo:
        page = todo.pop()
        for link in links_of(page):
            target = link.partition("#")[0]
            if target.endswith(".md") and not re.match(r"[a-z]+:", target):
                path = (page.parent / target).resolve()
                if path.exists() and path not in reached:
                    reached.add(path)
                    todo.append(path)
    assert [str(p.relative_to(REPO)) for p in PAGES if p not in reached] == []


def test_the_anchors_are_github_s(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text("# A page\n\n## Optional: `ik --batch`, fast\n\n```\n# not a heading\n```\n", encoding="utf-8")
    assert _anchors(page) == {"a-page", "optional-ik---batch-fast"}


def test_the_link_finder() -> None:
    page = REPO / "README.md"
    assert "docs/tutorial.md" in links_of(page)
    assert "docs/preview-demo.png" in links_of(page)
