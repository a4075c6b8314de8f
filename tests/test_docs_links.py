"""Every relative link in the README and every Markdown file under docs/ (the research record
included) names a file that exists and, with a ``#fragment``, a heading of that file (GitHub's
anchor rule)."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
LINK = re.compile(r"\]\(([^)\s]+)\)")


def anchor(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = heading.strip().lower().replace("`", "")
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    in_code = False
    found = set()
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            in_code = not in_code
        elif not in_code and line.startswith("#"):
            found.add(anchor(line.lstrip("#")))
    return found


def test_anchor_rule():
    assert anchor("Round 6: wrong-scale negatives (session of 2026-11-30, 01:51)") == \
        "round-6-wrong-scale-negatives-session-of-2026-11-30-0151"
    assert anchor("How far 0.70 is on the paper's nine") == "how-far-070-is-on-the-papers-nine"


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(document):
    broken = []
    for target in LINK.findall(document.read_text(encoding="utf-8")):
        if re.match(r"[a-z]+:", target):
            continue  # http(s), mailto: not checked offline
        path_part, _, fragment = target.partition("#")
        linked = (document.parent / path_part).resolve() if path_part else document
        if not linked.exists():
            broken.append(f"{target}: no such file")
        elif fragment and linked.suffix == ".md" and fragment not in anchors(linked):
            broken.append(f"{target}: no such heading")
    assert not broken, f"{document.name}: " + "; ".join(broken)


def test_the_development_log_is_the_scripts_output():
    """docs/research/log.md is generated: `python -m experiments.development.log_table --out docs/research/log.md`."""
    from experiments.development import log_table

    committed = (ROOT / "docs" / "research" / "log.md").read_text(encoding="utf-8")
    assert committed == log_table.table(), "regenerate: python -m experiments.development.log_table --out docs/research/log.md"
