"""Every relative link in the README and the docs points at a file that exists
(and, with a #fragment into a Markdown page, at a heading that exists), so that
moving a page or renaming a section cannot leave readers at a dead end."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Dict, List, Set, Tuple

import pytest

REPO = Path(__file__).resolve().parents[2]
PAGES = sorted(
    [
        REPO / "README.md",
        *(REPO / "docs").rglob("*.md"),
        REPO / "gui" / "README.md",
        REPO / "benchmarks" / "README.md",
        REPO / "third_party_notes" / "README.md",
    ]
)

# [text](target) and ![alt](target); the target ends at whitespace or ')'.
_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
_FENCE = re.compile(r"^\s*(```|~~~)")


def _prose_lines(text: str) -> List[str]:
    """The lines outside fenced code blocks (a link-like string in code is code)."""
    out, in_code = [], False
    for line in text.splitlines():
        if _FENCE.match(line):
            in_code = not in_code
            continue
        if not in_code:
            out.append(line)
    return out


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation other than '-' and
    '_' dropped, spaces to '-'."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _anchors(page: Path) -> Set[str]:
    """The anchors of a Markdown page's headings; repeats are numbered -1, -2, ..."""
    anchors: Set[str] = set()
    count: Dict[str, int] = {}
    for line in _prose_lines(page.read_text(encoding="utf-8")):
        m = re.match(r"#{1,6}\s+(.*?)\s*#*\s*$", line)
        if m:
            slug = _slug(m.group(1))
            n = count.get(slug, 0)
            anchors.add(slug if n == 0 else f"{slug}-{n}")
            count[slug] = n + 1
    return anchors


def _relative_links(page: Path) -> List[Tuple[int, str]]:
    links = []
    for i, line in enumerate(_prose_lines(page.read_text(encoding="utf-8")), 1):
        for target in _LINK.findall(line):
            if re.match(r"[a-zA-Z][a-zA-Z0-9+.-]*:", target) or target.startswith("//"):
                continue  # http:, https:, mailto:, ...
            links.append((i, target))
    return links


def test_the_pages_checked_exist_and_have_links():
    assert all(p.is_file() for p in PAGES), [str(p) for p in PAGES if not p.is_file()]
    assert sum(len(_relative_links(p)) for p in PAGES) > 20


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_every_relative_link_resolves(page: Path):
    broken = []
    for line, target in _relative_links(page):
        path_part, _, fragment = target.partition("#")
        dest = (page.parent / path_part).resolve() if path_part else page
        if not dest.exists():
            broken.append(f"line {line}: {target} (no such file: {dest.relative_to(REPO)})")
        elif fragment and dest.suffix == ".md" and fragment not in _anchors(dest):
            broken.append(
                f"line {line}: {target} (no heading #{fragment} in {dest.relative_to(REPO)})"
            )
    assert not broken, f"{page.relative_to(REPO)}: broken links: " + "; ".join(broken)


def test_the_anchor_rule_follows_github():
    # Anchors GitHub gives these headings (code spans, slashes, dots, apostrophes).
    assert _slug("Speed (`benchmarks/bench_recording.py`)") == "speed-benchmarksbench_recordingpy"
    assert _slug("Against Zeng and Morris's GF320 fit") == "against-zeng-and-morriss-gf320-fit"
    assert _slug("1. Calibration") == "1-calibration"
