"""The report's table by object family: where a method holds and where it does not, on the held-out objects.

One row per (family, method), from ``per_object.csv`` (``evaluation.subsets.subset_rows`` over
``evaluation.subsets.family_subsets``): objects, attempts, held per attempt with its Wilson 95% interval, six-direction
success per attempt, distinct held grasps per object and the share of objects with at least ``MIN_DISTINCT_HELD`` of
them. Pure text; nothing is drawn or read here.
"""

from __future__ import annotations

import html

import pandas as pd

from dexlite_pipeline.evaluation.labels import interval_text, method_label, percent_text
from dexlite_pipeline.evaluation.subsets import MIN_DISTINCT_HELD, family_subsets, subset_rows
from dexlite_pipeline.report.tables import HEADLINE_METHODS, number_text

HELD_OUT = "heldout"


def family_rows(metrics: pd.DataFrame, per_object: pd.DataFrame) -> pd.DataFrame:
    """``subset_rows`` of the held-out objects by family, for the main comparison's methods in its order; rows sorted by
    family, then method."""
    held_out = per_object[per_object["split"] == HELD_OUT]
    if held_out.empty:
        return subset_rows(metrics, held_out, {}, ())
    present = set(held_out["method"].astype(str))
    methods = [m for m in HEADLINE_METHODS if m in present] + sorted(present - set(HEADLINE_METHODS))
    rows = subset_rows(metrics, held_out, family_subsets(held_out["object_id"].astype(str)), methods)
    order = {m: k for k, m in enumerate(methods)}
    return rows.sort_values(["subset", "method"], key=lambda c: c.map(order) if c.name == "method" else c, kind="stable")


def family_table_html(metrics: pd.DataFrame | None, per_object: pd.DataFrame | None) -> str:
    """The section's table (empty text when there is no held-out object)."""
    if metrics is None or per_object is None or not len(per_object):
        return ""
    rows = family_rows(metrics, per_object)
    if rows.empty:
        return ""
    head = ("<tr><th>family</th><th>method</th><th>objects</th><th>attempts</th><th>held per attempt (95%)</th>"
            f"<th>six directions</th><th>distinct held / object</th><th>objects with ≥ {MIN_DISTINCT_HELD} distinct held</th></tr>")
    body = "".join(
        f"<tr><td>{html.escape(str(r.subset))}</td><td>{html.escape(method_label(str(r.method)))}</td><td>{int(r.objects)}</td>"
        f"<td>{int(r.attempts)}</td><td>{percent_text(r.held_rate)} ({interval_text(r.held_ci95_low, r.held_ci95_high)})</td>"
        f"<td>{percent_text(r.six_dir_rate)}</td><td>{number_text(r.distinct_held_per_object)}</td>"
        f"<td>{percent_text(r.objects_with_min_distinct)}</td></tr>"
        for r in rows.itertuples()
    )
    return f"<table><thead>{head}</thead><tbody>{body}</tbody></table>"
