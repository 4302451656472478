"""The numbers README.md and the shipped model's card quote, and whether docs/results.md carries each.

Run ``.venv/bin/python tests/results_page.py`` after editing the README or re-shipping the model: it prints
every quoted number that docs/results.md does not carry, with the line it is on (exit status 1 if any).
``--readme``, ``--card`` and ``--page`` read other files.

**Which numbers are quoted measurements.** In README.md and MODEL_CARD.md, outside code (fenced blocks and
`inline code` are commands and settings: ``--cores 2``, ``n=8``), a number is checked when it has one of
these forms:

1. a percentage: ``45.3%``, ``45.3 %``; a range or interval, one token: ``13-37%``, ``78.6%–84.9%``;
2. a ratio: ``6.6x``, ``6.6–7.1x``;
3. a time or a CPU cost: a number or range before CPU-seconds / CPU-s, CPU-minutes / CPU-min, CPU-hours,
   minutes / min, seconds, hours (``about 40 CPU-seconds``, ``13.9 min``);
4. a count of outcomes: ``18 of 42``, ``0/64`` (read as ``0 of 64``), ``7 in 10``;
5. any other number with a decimal point: ``10.3`` distinct held grasps, an AUC ``0.960``, table cells
   such as ``12.17``;
6. in prose (not in tables), a range of integers: ``28–32`` distinct held grasps, a bowl ``4–6``.

Not measurements, by rule: bare integers (the sizes of splits, attempts, seeds, steps and objects: the
protocol, not its outcome); integer ranges inside tables (the README's are the store layout's column
indices); dates and commit hashes; the card's section "How it was made" (its provenance: command, code
version, machine, date); a number before MB or GB (file sizes, memory); and the few patterns of
``NOT_MEASURED`` below, each with its reason. Numbers written in words (nine in ten, about an hour) are not
seen by this check.

**Found on the page** means docs/results.md, read with the same forms (and integer ranges in its tables
too), has the same token. Normalized alike on both sides: an en dash or a hyphen in a range, spaces before
``%``, thousands separators (``9,478`` is ``9478``), the units of form 3 spelled out or short
(``CPU-seconds`` is ``CPU-s``, ``minutes`` is ``min``), ``%`` on both ends of an interval. The README
rounds; the page gives the README's rounded value beside the measured one, so the match is exact.
"""

from __future__ import annotations

import argparse
import re
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
CARD = ROOT / "src" / "dexlite_pipeline" / "data" / "shadow-hand-household" / "MODEL_CARD.md"
PAGE = ROOT / "docs" / "results.md"
JOURNAL = ROOT / "docs" / "results_journal.md"

# Numbers that look like measurements and are not: (pattern, reason).
NOT_MEASURED = (
    (r"Wilson 95%|95% intervals?", "the confidence level of the intervals"),
    (r"2% of its size", "the preparation's tolerance against the file (a constant of objects/fidelity.py)"),
    (r"Python ≥ \d+\.\d+", "a version requirement"),
    (r"to 1\.5 mm", "the depth contact resolution backs every grasp out to (a setting)"),
    (r"friction 0\.6|0\.1 kg", "the lift test's physics settings (the card's limits)"),
    (r"at 8–12 cm", "the benchmark split's object sizes, set by the split"),
)
# The card's sections that are provenance, not measurement.
SKIPPED_SECTIONS = ("How it was made",)

NUM = r"(?:\d{1,3}(?:,\d{3})+|\d+)(?:\.\d+)?"
_L = r"(?<![\w.,/])"  # a number starts here: not inside a word, a decimal or a list of digits
_R = r"(?![\w/]|[.,]\d)"  # ... and ends here
DASH = r"\s*[–-]\s*"
TIME_UNITS = {
    "cpu-seconds": "CPU-s", "cpu-s": "CPU-s", "cpu-minutes": "CPU-min", "cpu-min": "CPU-min", "cpu-hours": "CPU-h",
    "minutes": "min", "min": "min", "seconds": "s", "hours": "h", "hour": "h",
}
TIME = "|".join(sorted(TIME_UNITS, key=len, reverse=True))
# (form, pattern, whether it counts inside tables), in the order they are read; each match is blanked
# before the next form reads the line, so a number is one token.
FORMS = (
    ("count", rf"{_L}({NUM}) of ({NUM}){_R}", True),
    ("count", rf"{_L}(\d+)/(\d+){_R}", True),
    ("in", rf"{_L}({NUM}) in (\d+){_R}", True),
    ("percent", rf"{_L}({NUM})\s*%?{DASH}({NUM})\s*%", True),
    ("percent", rf"{_L}({NUM})\s*%()", True),
    ("ratio", rf"{_L}({NUM})(?:{DASH}({NUM}))?x(?!\w)", True),
    ("time", rf"{_L}({NUM})(?:{DASH}({NUM}))?\s*((?i:{TIME}))(?![\w-])", True),
    ("decimal", rf"{_L}(\d+\.\d+){_R}()", True),
    ("range", rf"{_L}(\d+){DASH}(\d+)(?![\w%]|[.,]\d)", False),
)
DATE = r"\b\d{4}-\d{2}-\d{2}\b"
COMMIT = r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,40}(?:[+-][\w-]+)?\b"
SIZE = rf"{NUM}\s*(?:MB|GB)\b"


@dataclass(frozen=True)
class Quote:
    token: str  # the normalized number, e.g. "72–74%", "40 CPU-s", "18 of 42"
    line: int  # 1-based line of the file
    text: str  # the line, for the message


def _plain(number: str) -> str:
    return number.replace(",", "")


def _token(form: str, groups: tuple[str | None, ...]) -> str:
    a, b = _plain(groups[0]), _plain(groups[1]) if len(groups) > 1 and groups[1] else ""
    if form in ("count", "in"):
        return f"{a} {'of' if form == 'count' else 'in'} {b}"
    span = f"{a}–{b}" if b else a
    if form == "percent":
        return f"{span}%"
    if form == "ratio":
        return f"{span}x"
    if form == "time":
        return f"{span} {TIME_UNITS[groups[2].lower()]}"
    return span  # decimal, range


def _blank(text: str, pattern: str) -> str:
    return re.sub(pattern, lambda m: " " * len(m.group(0)), text)


def prose_lines(text: str, skip_sections: tuple[str, ...] = ()) -> list[tuple[int, str]]:
    """(line number, line) with code, link targets, dates, commits and skipped sections blanked out."""
    text = re.sub(r"^```.*?^```", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.M | re.S)
    text = re.sub(r"`[^`]*`", lambda m: re.sub(r"[^\n]", " ", m.group(0)), text)  # inline code, also across lines
    out, skipping = [], False
    for number, line in enumerate(text.splitlines(), start=1):
        if line.startswith("## "):
            skipping = line[3:].strip() in skip_sections
        if skipping:
            continue
        for pattern in (r"\]\([^)]*\)", DATE, COMMIT):
            line = _blank(line, pattern)
        out.append((number, line))
    return out


def quoted_numbers(text: str, *, skip_sections: tuple[str, ...] = (), allow: bool = True, ranges_in_tables: bool = False) -> list[Quote]:
    """Every measured number of a markdown text, by the forms of the module's docstring.

    ``allow``: drop the NOT_MEASURED patterns first (the README and the card); ``ranges_in_tables``:
    integer ranges count in tables too (the page, whose README columns quote them).
    """
    quotes = []
    for number, line in prose_lines(text, skip_sections):
        original, in_table = line, line.lstrip().startswith("|")
        if allow:
            for pattern, _ in NOT_MEASURED:
                line = _blank(line, pattern)
        line = _blank(line, SIZE)
        for form, pattern, tables in FORMS:
            if in_table and not (tables or ranges_in_tables):
                continue
            for match in re.finditer(pattern, line):
                quotes.append(Quote(_token(form, match.groups()), number, original.strip()))
            line = _blank(line, pattern)
    return quotes


def readme_numbers(path: Path = README) -> list[Quote]:
    return quoted_numbers(path.read_text())


def card_numbers(path: Path = CARD) -> list[Quote]:
    return quoted_numbers(path.read_text(), skip_sections=SKIPPED_SECTIONS)


def page_tokens(path: Path = PAGE) -> set[str]:
    return {quote.token for quote in quoted_numbers(path.read_text(), allow=False, ranges_in_tables=True)}


def missing(quotes: list[Quote], page: set[str]) -> list[Quote]:
    """The quotes whose number the page does not carry."""
    return [quote for quote in quotes if quote.token not in page]


# What the page names for each number's provenance (the machines as the journal names them).
PAGE_COMMIT = r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,40}\b"
PAGE_DATE = r"\b20\d\d-[01]\d-[0-3]\d\b"
PAGE_MACHINE = r"AMD EPYC|Intel Xeon|machine [AB]\b"
PROVENANCE = {"commit": PAGE_COMMIT, "date": PAGE_DATE, "machine": PAGE_MACHINE}


def names_provenance(text: str) -> list[str]:
    """Which of commit, date and machine the text does not name."""
    return [what for what, pattern in PROVENANCE.items() if not re.search(pattern, text)]


def blocks(text: str) -> list[tuple[str, int, list[str]]]:
    """The page as (kind, first line, lines): kind "heading", "table" or "paragraph"; blank lines separate."""
    out: list[tuple[str, int, list[str]]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        kind = "heading" if line.startswith("#") else "table" if line.lstrip().startswith("|") else "paragraph" if line.strip() else None
        if kind is None:
            continue
        if kind != "heading" and out and out[-1][0] == kind and out[-1][1] + len(out[-1][2]) == number:
            out[-1][2].append(line)
        else:
            out.append((kind, number, [line]))
    return out


def table_cells(line: str) -> list[str]:
    return [cell.strip() for cell in line.strip().strip("|").split("|")]


def provenance_problems(text: str) -> list[str]:
    """Tables without their commit, date and machine; numbers in prose outside a table and its "Measured" line.

    A table carries its provenance in columns named commit, date and machine (every row filled), or in the
    paragraph right after it, which starts with "Measured:" and names all three. Every ``##`` section names
    all three too.
    """
    problems = []
    parts = blocks(text)
    for k, (kind, first, lines) in enumerate(parts):
        if kind == "table":
            header = [cell.lower() for cell in table_cells(lines[0])]
            if all(what in header for what in PROVENANCE):
                for offset, row in enumerate(lines[2:], start=2):
                    cells = dict(zip(header, table_cells(row)))
                    lacking = [what for what, pattern in PROVENANCE.items() if not re.search(pattern, cells.get(what, ""))]
                    if lacking:
                        problems.append(f"line {first + offset}: the row names no {', '.join(lacking)}")
                continue
            after = parts[k + 1] if k + 1 < len(parts) else None
            if after is None or after[0] != "paragraph" or not after[2][0].startswith("Measured:"):
                problems.append(f"line {first}: the table has no commit, date and machine columns and no 'Measured:' line after it")
            elif lacking := names_provenance(" ".join(after[2])):
                problems.append(f"line {after[1]}: the 'Measured:' line names no {', '.join(lacking)}")
        elif kind == "paragraph" and not lines[0].startswith("Measured:"):
            numbers = quoted_numbers("\n".join(lines), ranges_in_tables=True)
            if numbers:
                problems.append(f"line {first}: numbers outside a table and its 'Measured:' line: {', '.join(q.token for q in numbers)}")
    for section in re.split(r"^(?=## )", text, flags=re.M)[1:]:
        if lacking := names_provenance(section):
            problems.append(f"section {section.splitlines()[0]!r} names no {', '.join(lacking)}")
    return problems


def github_anchor(heading: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation dropped, spaces as hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def journal_anchors(path: Path = JOURNAL) -> set[str]:
    return {github_anchor(line.lstrip("#")) for line in path.read_text().splitlines() if line.startswith("#")}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--readme", type=Path, default=README)
    parser.add_argument("--card", type=Path, default=CARD)
    parser.add_argument("--page", type=Path, default=PAGE)
    parser.add_argument("--list", action="store_true", help="print every quoted number, found or not")
    args = parser.parse_args(argv)
    page = page_tokens(args.page)
    status = 0
    for name, quotes in (("README", readme_numbers(args.readme)), ("model card", card_numbers(args.card))):
        absent = missing(quotes, page)
        if args.list:
            for quote in quotes:
                print(f"{name}:{quote.line}: {quote.token}{'' if quote.token in page else '   NOT ON THE PAGE'}")
        print(f"{name}: {len(quotes)} quoted numbers, {len(absent)} not on {args.page.name}")
        for quote in absent:
            print(f"  {name}:{quote.line}: {quote.token!r} not on {args.page.name}: {quote.text[:140]}")
        status |= bool(absent)
    return status


if __name__ == "__main__":
    sys.exit(main())
