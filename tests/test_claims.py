"""Every comparative sentence in the README and the docs carries its evidence: a paragraph that says
one method "beats", "outperforms", is "significantly" ahead of, "level with" or "separated" from
another also gives a p-value or an interval (or says the test does not separate them). "Level" drawn
from p > 0.05 is refused outright: not separated is not level (docs/statistics.md)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
COMPARATIVE = re.compile(
    r"\b(beats?|outperforms?|significantly|superior to|separated from"
    r"|separates? (methods|them|the two|controllers))\b",
    re.I,
)
EVIDENCE = re.compile(
    r"\bp\s[=<>]|p-value|\[\d[\d.]*, \d[\d.]*\]|\{\d[\d.]*, \d[\d.]*\}|not separated|does not separate", re.I
)
LEVEL = re.compile(r"\b(are|were|is|was)\s+level\b|\blevel\s+with\b", re.I)


def _paragraphs(page: Path) -> list[str]:
    """Prose paragraphs and list items, code blocks and tables left out."""
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    blocks = re.split(r"\n\s*\n|\n(?=\s*[-*] |\s*\d+\. )", text)
    return [b for b in blocks if b.strip() and not b.lstrip().startswith(("|", "#"))]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_comparative_sentence_gives_its_evidence(page: Path):
    bare = [p for p in _paragraphs(page) if COMPARATIVE.search(p) and not EVIDENCE.search(p)]
    assert not bare, f"{page.name}: a comparison without a p-value or interval:\n" + "\n---\n".join(
        " ".join(b.split())[:300] for b in bare
    )


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_no_page_calls_two_methods_level(page: Path):
    unquoted = [(p, re.sub(r'"[^"]*"', "", p)) for p in _paragraphs(page)]  # a rule may quote the word
    said = [" ".join(p.split())[:300] for p, bare in unquoted if LEVEL.search(bare)]
    assert not said, f"{page.name}: 'level' is not what a p-value above 0.05 shows:\n" + "\n---\n".join(said)
