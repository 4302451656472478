"""The report's first screen: what a reader came for, whole on a 1280 × 900 screen without scrolling.

Three parts, all read from metrics.csv's rows of one split (held-out objects when evaluated):

- the verdict, at most ``VERDICT_WORDS`` words: the recommended way of making grasps (the
  generating method with the highest lift rate per attempt), its rate and 95% interval against
  optimization from scratch's (or, without that or when it is the best, against the runner-up),
  distinct held grasps per object for both and the ratio of their CPU-seconds per distinct held
  grasp, each where the run measured it;
- the held-per-attempt chart: lift and six directions side by side with their intervals (``plots``);
- the summary table: at most seven columns, so it fits beside the chart.

Everything else (every measure of every method, the energy filter, the write-up's lenient
test, costs per stage, the run's facts and settings) is below, in ``page``.
"""

from __future__ import annotations

import html
import math

from dexlite_pipeline.evaluation.labels import interval_text, method_label, percent_text, split_label
from dexlite_pipeline.report.plots import held_per_attempt_plot, img_tag
from dexlite_pipeline.report.tables import HEADLINE_METHODS, cost_text, headline_rows, interval_columns, is_finite, number_text, rate_cell

VERDICT_WORDS = 40  # the verdict's length limit, in words (whitespace-separated)
SCRATCH = "optimization"  # the baseline every other way of making grasps is measured against
# Ways of making grasps for an object: every main method but imported DexGraspNet grasps.
GENERATING_METHODS = tuple(m for m in HEADLINE_METHODS if m != "dexgraspnet")
# Method names inside the verdict: at most four words each, so that the verdict stays within its words.
VERDICT_NAMES = {
    "cvae_ranked_post": "post-optimized ranked CVAE samples",
    "cvae_post": "post-optimized CVAE samples",
    "random_post": "post-optimized random starts",
    "shipped_post": "post-optimized shipped-model samples",
    "cvae_ranked": "raw ranked CVAE samples",
    "cvae_raw": "raw CVAE samples",
    "shipped_raw": "raw shipped-model samples",
    "optimization": "optimization from scratch",
}
DISTINCT = "distinct_held_per_object_mean"
START_DEPTH = "held_start_depth_median_mm"
CPU_PER_DISTINCT = "cpu_seconds_per_distinct_held_grasp"


def first_screen_rows(metrics_df):
    """The main comparison's rows on one split: the held-out objects when evaluated, else the first split listed."""
    rows = headline_rows(metrics_df)
    if rows is None or not len(rows) or "split" not in rows.columns:
        return rows
    splits = rows["split"].astype(str)
    split = "heldout" if (splits == "heldout").any() else splits.iloc[0]
    return rows[splits == split]


def ranked_generating_rows(rows):
    """The generating methods with a lift rate, highest rate first (ties keep the table's order); None when there are none."""
    if rows is None or not len(rows) or "lift_success_rate" not in rows.columns:
        return None
    generating = rows[rows["method"].astype(str).isin(GENERATING_METHODS)].dropna(subset=["lift_success_rate"])
    if not len(generating):
        return None
    return generating.sort_values("lift_success_rate", ascending=False, kind="stable")


def recommended_method(rows) -> str | None:
    """The generating method with the highest lift rate per attempt; None when no generating method was lift-tested."""
    ranked = ranked_generating_rows(rows)
    return None if ranked is None else str(ranked["method"].iloc[0])


def reference_row(ranked):
    """What the best is measured against: optimization from scratch, or the runner-up when scratch is the best or absent."""
    best = str(ranked["method"].iloc[0])
    scratch = ranked[ranked["method"].astype(str) == SCRATCH]
    if best != SCRATCH and len(scratch):
        return scratch.iloc[0]
    return ranked.iloc[1] if len(ranked) > 1 else None


def verdict_name(method: str) -> str:
    """A method's name inside the verdict (``VERDICT_NAMES``; else its readable label, lower-cased)."""
    if method in VERDICT_NAMES:
        return VERDICT_NAMES[method]
    label = method_label(method)
    return label[:1].lower() + label[1:] if len(label) > 1 and label[1].islower() else label


def _where(best, reference, split: str) -> str:
    """ "on 20 held-out objects"; without a count ("on the held-out objects") when it is unknown or the two rows differ in it."""
    counts = {row.get("n_objects") for row in (best, reference) if row is not None}
    count = next(iter(counts)) if len(counts) == 1 else None
    objects = split_label(split)
    if not is_finite(count):
        return f"on the {objects}"
    if int(count) == 1 and objects.endswith("objects"):
        objects = objects[:-1]
    return f"on {int(count)} {objects}"


def _held(row, label: bool) -> str:
    """ "42.0% held per attempt (95% CI 35–49%)" (``label``), else "30.1% (25–36%)"; no brackets without an interval."""
    interval = interval_text(*interval_columns(row, "lift_success"))
    rate = percent_text(row["lift_success_rate"])
    if label:
        return f"{rate} held per attempt" + (f" (95% CI {interval}%)" if interval else "")
    return rate + (f" ({interval}%)" if interval else "")


def _distinct_clause(best, reference) -> str | None:
    """ "Distinct held grasps per object: 3.2 vs 2.1" (one number without a reference); None when not measured."""
    if not is_finite(best.get(DISTINCT)):
        return None
    if reference is None:
        return f"Distinct held grasps per object: {number_text(best[DISTINCT])}"
    if not is_finite(reference.get(DISTINCT)):
        return None
    return f"Distinct held grasps per object: {number_text(best[DISTINCT])} vs {number_text(reference[DISTINCT])}"


def _cpu_ratio(best, reference) -> float | None:
    """The best's CPU-seconds per distinct held grasp over the reference's; None unless both are finite and positive."""
    if reference is None:
        return None
    values = [float(row.get(CPU_PER_DISTINCT)) if is_finite(row.get(CPU_PER_DISTINCT)) else math.nan for row in (best, reference)]
    if not all(math.isfinite(v) and v > 0 for v in values):
        return None
    return values[0] / values[1]


def ratio_text(ratio: float) -> str:
    """ "0.25×", "4×", "120×": two significant digits, whole numbers from 10 on."""
    return f"{ratio:.0f}×" if ratio >= 10 else f"{ratio:.2g}×"


def _second_sentence(distinct: str | None, ratio: float | None) -> str:
    """The diversity and cost sentence from the clauses the run has; empty when it has neither."""
    cost = f"{ratio_text(ratio)} the CPU-seconds per distinct held grasp" if ratio is not None else None
    if distinct and cost:
        return f"{distinct}, at {cost}."
    if distinct:
        return f"{distinct}."
    return f"It takes {cost}." if cost else ""


def word_count(text: str) -> int:
    """The words of ``text`` as the verdict's limit counts them: whitespace-separated pieces ("+" and "(95%" are words)."""
    return len(text.split())


def _within_words(first: str, distinct: str | None, ratio: float | None) -> str:
    """The verdict with as much of the second sentence as fits in ``VERDICT_WORDS`` (cost dropped first, then diversity)."""
    for kept in ((distinct, ratio), (distinct, None), (None, None)):
        text = f"{first} {_second_sentence(*kept)}".strip()
        if word_count(text) <= VERDICT_WORDS:
            return text
    return first


def verdict_sentence(rows) -> str:
    """The recommended way of making grasps, in at most ``VERDICT_WORDS`` words, from ``first_screen_rows``' rows."""
    ranked = ranked_generating_rows(rows)
    if ranked is None:
        return "No way of making grasps was lift-tested in this run."
    best = ranked.iloc[0]
    reference = reference_row(ranked)
    split = str(best["split"]) if "split" in ranked.columns else "heldout"
    where = _where(best, reference, split)
    if float(best["lift_success_rate"]) <= 0:
        return f"No way of making grasps held an object in the lift test {where} ({len(ranked)} evaluated)."
    if reference is None:
        first = f"Recommended {where}: {verdict_name(str(best['method']))}, the only way of making grasps evaluated, {_held(best, True)}."
    else:
        first = (f"Recommended {where}: {verdict_name(str(best['method']))}, {_held(best, True)} "
                 f"vs {_held(reference, False)} for {verdict_name(str(reference['method']))}.")  # fmt: skip
    return _within_words(first, _distinct_clause(best, reference), _cpu_ratio(best, reference))


def _has_values(rows, column: str) -> bool:
    """Whether any row has a value (a number or ∞) in ``column``."""
    return column in rows.columns and rows[column].notna().any()


def _name_cell(row, best: str | None) -> str:
    method = str(row["method"])
    mark = " <span class='pick'>recommended</span>" if method == best else ""
    return f"<td class='name' title='{html.escape(method)}'>{html.escape(method_label(method))}{mark}</td>"


# The summary table's columns after the method: (header, column it needs or None, cell of a row).
SUMMARY_COLUMNS = (
    ("held: lift test", None, lambda row: rate_cell(row, "lift_success")),
    ("held: six pushes", None, lambda row: rate_cell(row, "six_dir_success")),
    ("distinct held / object", DISTINCT, lambda row: f"<td>{number_text(row.get(DISTINCT))}</td>"),
    ("start depth (mm, median of held)", START_DEPTH, lambda row: f"<td>{number_text(row.get(START_DEPTH))}</td>"),
    ("CPU s / distinct held grasp", CPU_PER_DISTINCT, lambda row: f"<td>{cost_text(row.get(CPU_PER_DISTINCT))}</td>"),
)


def summary_table_html(rows, best: str | None = None) -> str:
    """The first screen's table (at most seven columns): method, both rates with intervals, and the diversity, depth and
    cost columns the run measured; the ``best`` method's row marked."""
    if rows is None or not len(rows):
        return "<p>No method was evaluated.</p>"
    columns = [(header, cell) for header, needs, cell in SUMMARY_COLUMNS if needs is None or _has_values(rows, needs)]
    head = "<tr><th class='name'>method</th>" + "".join(f"<th>{html.escape(header)}</th>" for header, _ in columns) + "</tr>"
    body = []
    for _, row in rows.iterrows():
        css = " class='best'" if str(row["method"]) == best else ""
        body.append(f"<tr{css}>" + _name_cell(row, best) + "".join(cell(row) for _, cell in columns) + "</tr>")
    return f"<table class='summary' id='summary-table'><thead>{head}</thead><tbody>{''.join(body)}</tbody></table>"


FIRST_SCREEN_NOTE = (
    "<p class='note'>Held: the object rose with the hand (lift test) / stayed put under a push of about its weight along each "
    "of ±x, ±y, ±z (six pushes), per attempt. Small numbers and error bars: object-level bootstrap 95% interval. "
    "Start depth: how far the held grasps' hand starts inside the object when the lift test begins. Every measure, the "
    "energy filter and the run are below.</p>"
)


def first_screen_html(metrics_df) -> str:
    """The verdict, then the held-per-attempt chart beside the summary table, as one block at the top of the page."""
    rows = first_screen_rows(metrics_df)
    chart = held_per_attempt_plot(rows)
    picture = img_tag(chart, "held per attempt by method") if chart else "<p>No grasp was simulated in this run.</p>"
    return (
        f"<section class='first-screen'><p class='verdict' id='verdict'>{html.escape(verdict_sentence(rows))}</p>"
        f"<div class='glance'><div class='chart' id='held-chart'>{picture}</div>"
        f"<div class='summary'>{summary_table_html(rows, recommended_method(rows))}{FIRST_SCREEN_NOTE}</div></div></section>"
    )
