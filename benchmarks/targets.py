"""Every target the benchmark pages state, gathered on one page with each page's date and
commit: where the project stands, read from the pages themselves and never typed.

Each page of the suite states its targets and whether they are met (a list item or a
sentence opening with "Target" that names a target or moonshot and says "met", or the rows
of a table with a target column). This collects those
lines from a results folder, page by page, with the machine line each page starts with
(its commit and date), and writes ``targets.md`` beside them.

Usage: ``python -m benchmarks.targets [--results DIR] [--out FILE]`` (default: the shipped
pages in ``benchmarks/results``, the page to ``runs/benchmarks/targets.md``); ``--out
benchmarks/results/targets.md`` updates the shipped page.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from benchmarks.common import OUT, RESULTS, parser, write

PAGE_NAME = "targets.md"
_TARGET = re.compile(r"\b(targets?|moonshot)\b", re.IGNORECASE)
_MET = re.compile(r"\bmet\b")
#: How a page's target statements begin: a list item, or a sentence opening with the word.
_STATEMENT = ("* ", "- ", "Target")
_RULE = re.compile(r"^\|(\s*:?-+:?\s*\|)+\s*$")


def page_targets(text: str) -> list[str]:
    """The target lines of one page: list items and sentences opening with "Target" that
    name a target and whether it is met, and the rows of a table with a target column that
    say "met", under that table's header."""
    lines = text.splitlines()
    out: list[str] = []
    header: list[str] = []
    header_shown = False
    for i, line in enumerate(lines):
        if line.startswith("|"):
            if i + 1 < len(lines) and _RULE.match(lines[i + 1]):
                header, header_shown = [line, lines[i + 1]], False
                continue
            if _MET.search(line) and header and _TARGET.search(header[0]):
                if not header_shown:
                    out += ["", *header]
                    header_shown = True
                out.append(line)
        elif line.startswith(_STATEMENT) and _TARGET.search(line) and _MET.search(line):
            out.append(line)
    return out


def machine(text: str) -> str:
    """A page's machine line (its commit and date), or a note that it has none."""
    for line in text.splitlines():
        if line.startswith("Machine:"):
            return line
    return "(the page names no machine, commit or date)"


def report(results: Path, out: Path) -> list[str]:
    """The page's body: each page of ``results`` with targets, linked from ``out``."""
    body = [
        f"The targets the pages in `{results.name}/` state, page by page, copied from them "
        "with the line that names each page's machine, commit and date. A page measured on "
        "another commit than another is not re-run here: re-run its command "
        "(benchmarks/README.md).",
    ]
    for page in sorted(results.glob("*.md")):
        if page.name == PAGE_NAME:
            continue
        text = page.read_text()
        found = page_targets(text)
        if found:
            link = os.path.relpath(page, out.resolve().parent)
            body += ["", f"## [{page.name}]({link})", "", machine(text), "", *found]
    return body


def run(results: Path = RESULTS, out: Path = OUT / PAGE_NAME) -> Path:
    """Gather the targets of the pages in ``results`` into ``out``."""
    return write(out, "Benchmark targets", report(results.resolve(), out))


def main(argv: list[str] | None = None) -> int:
    ap = parser("benchmarks.targets", __doc__, PAGE_NAME)
    ap.add_argument("--results", type=Path, default=RESULTS, help="the folder of pages to read")
    args = ap.parse_args(argv)
    if not args.results.is_dir():
        ap.error(f"--results {args.results}: not a folder")
    run(args.results, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
