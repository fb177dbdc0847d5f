"""The documentation's links: every relative link and image in README.md and docs/ names a
file or folder of the repository, and every ``#anchor`` a heading of the page it names; the
README's test command is the one ``.ci/run`` runs."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
PAGES = sorted([REPO / "README.md", *(REPO / "docs").rglob("*.md")])
#: ``[text](target)`` and ``![alt](target)``, the target without spaces (an optional title
#: after a space is left out).
LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
FENCE = re.compile(r"^(```|~~~)")


def prose(text: str, spans: bool = True) -> str:
    """The text outside fenced code blocks, and with ``spans`` outside inline code spans."""
    kept, fenced = [], False
    for line in text.splitlines():
        if FENCE.match(line.strip()):
            fenced = not fenced
            continue
        if not fenced:
            kept.append(re.sub(r"`[^`]*`", "``", line) if spans else line)
    return "\n".join(kept)


def slug(heading: str) -> str:
    """The anchor GitHub gives a heading: lower case, markup and punctuation dropped (hyphens
    and underscores kept), spaces as hyphens."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading.strip()).lower()
    text = re.sub(r"[^\w\- ]", "", text.replace("`", ""))
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    found: dict[str, int] = {}
    out = set()
    for line in prose(page.read_text(), spans=False).splitlines():
        if m := re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line):
            base = slug(m.group(1))
            n = found.get(base, 0)
            found[base] = n + 1
            out.add(base if n == 0 else f"{base}-{n}")
    return out


def links(page: Path) -> list[str]:
    return [
        target
        for target in LINK.findall(prose(page.read_text()))
        if not re.match(r"^[a-z][a-z0-9+.-]*:", target)  # http:, https:, mailto: ...
    ]


def test_the_pages_are_found():
    names = {p.relative_to(REPO).as_posix() for p in PAGES}
    assert {"README.md", "docs/training.md", "docs/results.md"} <= names
    assert any(n.startswith("docs/experiments/") for n in names)


@pytest.mark.parametrize("page", PAGES, ids=[p.relative_to(REPO).as_posix() for p in PAGES])
def test_every_link_resolves(page):
    bad = []
    for target in links(page):
        path, _, anchor = target.partition("#")
        where = (page.parent / path).resolve() if path else page
        if not where.exists():
            bad.append(f"{target}: no such file")
        elif not where.is_relative_to(REPO):
            bad.append(f"{target}: outside the repository")
        elif anchor and where.suffix == ".md" and anchor not in anchors(where):
            bad.append(f"{target}: no heading #{anchor} in {where.relative_to(REPO)}")
    assert not bad, "\n".join(bad)


def test_the_checker_sees_bad_links(tmp_path):
    page = tmp_path / "p.md"
    page.write_text(
        "# A `b` c, d\n[x](p.md#a-b-c-d) [y](missing.md) ![z](img.png) [w](https://e.org)\n"
        "```\n[not](a-link.md)\n```\n"
    )
    assert links(page) == ["p.md#a-b-c-d", "missing.md", "img.png"]
    assert anchors(page) == {"a-b-c-d"}


def test_readme_runs_the_tests_as_ci_does():
    """Line 36 of the README is the test command that ``.ci/run`` runs verbatim."""
    command = (REPO / "README.md").read_text().splitlines()[35]
    assert command.startswith("python -m venv .venv && ") and "pytest -q" in command
    ci = (REPO / ".ci" / "run").read_text().splitlines()
    assert any(line.startswith(command + " ||") for line in ci)


def test_readme_results_are_copied_from_the_results_page():
    """The README's results rows are the generated page's, word for word (one source)."""
    readme = (REPO / "README.md").read_text()
    page = (REPO / "docs" / "results.md").read_text()
    assert page.startswith("# Results\n") and "Generated on " in page
    section = readme.split("\n## Results\n", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| ")]
    assert len(rows) > 2 and all(row in page.splitlines() for row in rows)
    commit = page.split("at commit `", 1)[1].split("`", 1)[0]
    assert f"commit `{commit}`" in section
