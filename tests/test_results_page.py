"""docs/results.md is the current page: short, every number on it with its commit, date and machine, and every
number the README and the shipped model's card quote found on it.

(a) the page has fewer than 300 lines (the dated record of every measurement is docs/results_journal.md);
(b) every table names a commit (7 or more hex digits), a date (YYYY-MM-DD) and a machine (as the journal names
    them: AMD EPYC, Intel Xeon, machine A or B), in columns named commit, date and machine or in the
    "Measured:" line right after it; every section names all three; prose outside the tables and their
    "Measured:" lines carries no measured number, so no number is without its provenance;
(c) every measured number that README.md and MODEL_CARD.md quote is on the page. Which numbers count is the
    rule of tests/results_page.py's docstring: percentages, ratios (6.6x), times and CPU costs, counts
    ("18 of 42", "0/64", "7 in 10"), any other decimal number, and integer ranges in prose; not bare integers
    (sizes of splits, attempts, seeds), code, dates, commits, the card's provenance section, file sizes, and
    a short allow-list of settings that look like results (each with its reason). The rule itself is tested
    on a small text and on a README and a card with one number changed, which must fail;
(d) every link into docs/results_journal.md names one of its sections.

After editing the README or re-shipping the model, `.venv/bin/python tests/results_page.py` lists what (c) misses.
"""

import re

import results_page as rp

MAX_LINES = 300


def test_the_page_is_short():
    lines = rp.PAGE.read_text().splitlines()
    assert len(lines) < MAX_LINES, f"docs/results.md has {len(lines)} lines (fewer than {MAX_LINES}): details belong in docs/results_journal.md"


def test_every_table_and_section_names_its_commit_date_and_machine():
    problems = rp.provenance_problems(rp.PAGE.read_text())
    assert not problems, "docs/results.md:\n" + "\n".join(problems)


def test_the_provenance_check_can_fail():
    table = "| method | held |\n| --- | --- |\n| optimization | 43.2% |\n"
    good = f"## A\n\n{table}\nMeasured: commit 1c6f24f, 2026-12-04, AMD EPYC 2 cores (busy).\n"
    assert rp.provenance_problems(good) == []
    assert rp.provenance_problems(good.replace("1c6f24f, ", "")), "a Measured line without its commit"
    assert rp.provenance_problems(good.replace("AMD EPYC", "a machine")), "a Measured line without a machine"
    assert rp.provenance_problems(f"## A\n\n{table}\nSome words.\n"), "a table without a Measured line"
    assert rp.provenance_problems(good + "\nAnd 12.5% more.\n"), "a number in prose"
    columns = "## A\n\n| held | commit | date | machine |\n| --- | --- | --- | --- |\n| 43.2% | 1c6f24f | 2026-12-04 | machine A |\n"
    assert rp.provenance_problems(columns) == []
    assert rp.provenance_problems(columns.replace("2026-12-04", "")), "a row without its date"


def test_the_rule_reads_the_numbers_it_says_it_reads():
    text = (
        "It holds 69% (72–74% at three seeds; 13-37 % here), 10.3 grasps, 6.6–7.1x, 9,478 CPU-seconds, about 10 minutes,\n"
        "2–3 CPU-minutes, 18 of 42, 0/64 hold, 7 in 10, a bowl 4–6.\n"
        "Not these: 95% intervals, 2% of its size, Python ≥ 3.10, backed out to 1.5 mm, `--cores 2`, n=32 objects,\n"
        "2026-12-04, 1c6f24f, 33.2 MB, 16 attempts, at most 2 mm, friction 0.6, 1280 x 900.\n"
        "| column | meaning |\n| --- | --- |\n| 0–2 | position |\n| 81.9% (78.6%–84.9%) | 12.17 |\n"
    )
    tokens = sorted(quote.token for quote in rp.quoted_numbers(text))
    assert tokens == sorted([
        "69%", "72–74%", "13–37%", "10.3", "6.6–7.1x", "9478 CPU-s", "10 min", "2–3 CPU-min", "18 of 42", "0 of 64", "7 in 10", "4–6",
        "81.9%", "78.6–84.9%", "12.17",
    ]), tokens


def test_every_number_the_readme_and_the_card_quote_is_on_the_page():
    page = rp.page_tokens()
    readme, card = rp.readme_numbers(), rp.card_numbers()
    assert len(readme) >= 20 and len(card) >= 100, "the rule reads far fewer numbers than the README and the card quote"
    absent = [f"README:{q.line}: {q.token}" for q in rp.missing(readme, page)] + [f"MODEL_CARD.md:{q.line}: {q.token}" for q in rp.missing(card, page)]
    assert not absent, "quoted but not on docs/results.md (update the page, or the quote):\n" + "\n".join(absent)


def test_a_changed_readme_or_card_number_fails(tmp_path):
    page = rp.page_tokens()
    readme = tmp_path / "README.md"
    text = rp.README.read_text()
    assert "it holds 96.9% of its" in text, "the README's sentence this test changes has moved: update the test"
    readme.write_text(text.replace("it holds 96.9% of its", "it holds 93.6% of its", 1))
    assert [q.token for q in rp.missing(rp.readme_numbers(readme), page)] == ["93.6%"]
    card = tmp_path / "MODEL_CARD.md"
    text = rp.CARD.read_text()
    assert "| 96.7% (94.9%–97.9%) |" in text, "the card's row this test changes has moved: update the test"
    card.write_text(text.replace("| 96.7% (94.9%–97.9%) |", "| 93.1% (94.9%–97.9%) |", 1))
    assert [q.token for q in rp.missing(rp.card_numbers(card), page)] == ["93.1%"]


def test_links_into_the_journal_name_its_sections():
    anchors = rp.journal_anchors()
    links = re.findall(r"\]\(results_journal\.md#([^)]+)\)", rp.PAGE.read_text())
    assert links, "the page links to no section of the journal"
    assert not [link for link in links if link not in anchors], "links to no section of docs/results_journal.md"
