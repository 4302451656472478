"""The report's tables as HTML: which rows the main comparison and the learning ladder show, the wide
table of every method's measures with rates and intervals, the ladder, the folded full table, the one-sentence result, and the
formatting of their cells. Pure text from metrics.csv's frame; nothing is drawn or read here.
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping

import numpy as np

from dexlite_pipeline.evaluation.labels import interval_text, method_label, percent_text, rung_label, seconds_text, split_label


# Every column of metrics.csv worth a reader's look, for the folded full table at the end.
TABLE_COLUMNS = (
    "method", "split", "rung", "n_grasps", "n_invalid", "n_objects", "lift_success_rate", "lift_success_ci95_low", "lift_success_ci95_high",
    "lift_success_boot_ci95_low", "lift_success_boot_ci95_high", "object_success_rate", "six_dir_success_rate",
    "six_dir_success_ci95_low", "six_dir_success_ci95_high", "six_dir_success_boot_ci95_low", "six_dir_success_boot_ci95_high",
    "penetration_mean_mm", "penetration_p95_mm", "held_start_depth_median_mm", "held_start_depth_p90_mm", "contact_distance_mean_mm",
    "E_fc_mean", "energy_threshold_pass_rate",
    "joint_entropy_bits", "held_joint_entropy_bits", "pca_explained_variance_k1", "pca_explained_variance_k3",
    "n_held", "distinct_held_total", "distinct_held_per_object_mean", "distinct_held_per_attempt", "surface_coverage_mean",
    "filtered_n_grasps", "filtered_lift_success_rate", "filtered_lift_success_ci95_low", "filtered_lift_success_ci95_high",
    "filtered_six_dir_success_rate", "filtered_n_held", "filtered_distinct_held_total", "filtered_distinct_held_per_object_mean",
    "filtered_distinct_held_per_attempt", "filtered_surface_coverage_mean", "seconds_per_grasp", "cpu_seconds_per_held_grasp",
    "cpu_seconds_per_distinct_held_grasp", "filtered_cpu_seconds_per_held_grasp", "filtered_cpu_seconds_per_distinct_held_grasp",
    "E_post_median_initial", "E_post_median_final", "iterations_to_random_final_E_post", "threshold_reached_fraction", "convergence_ratio",
    "writeup_protocol_lift_success_rate", "writeup_protocol_lift_success_ci95_low", "writeup_protocol_lift_success_ci95_high",
    "fit_rotation_error_deg_median", "fit_translation_error_mm_median", "fit_joint_error_rad_mean",
)  # fmt: skip
# Readable headers of the ladder's own columns (the fit rung's pose errors against the grasps it reconstructs).
LADDER_COLUMN_LABELS = {
    "fit_rotation_error_deg_median": "palm rotation error (°, median)",
    "fit_translation_error_mm_median": "palm position error (mm, median)",
    "fit_joint_error_rad_mean": "joint error (rad, mean)",
}
LENIENT = "writeup_protocol_lift_success"  # the same grasps under the DexLite write-up's (Murali) more lenient lift test (evaluate.writeup_protocol)
# The methods of the main comparison, in the order the tables and charts list them.
HEADLINE_METHODS = ("cvae_post", "cvae_ranked_post", "random_post", "cvae_raw", "cvae_ranked", "shipped_post", "shipped_raw", "optimization", "dexgraspnet")
HEADLINE_METHOD = "cvae_post"  # the pipeline's product: the sentence leads with it when present
RUNG_ORDER = ("fit", "in_distribution", "heldout")
# Within a rung: each kind of start raw, then post-optimized; the random-start baseline last.
LADDER_METHOD_ORDER = ("cvae_recon", "cvae_recon_post", "cvae_prior_train", "cvae_prior_train_post", "cvae_raw", "cvae_post", "random_post")


def headline_rows(metrics_df):
    """The rows of the main comparison: the evaluation's own methods, one row per (method, split), in table order.

    Rows of the learning ladder (a ``rung`` value and a method outside the main ones) are
    left to ``ladder_rows``; a main method that also carries a rung appears here once.
    """
    if metrics_df is None or not len(metrics_df):
        return metrics_df
    main = metrics_df[metrics_df["method"].astype(str).isin(HEADLINE_METHODS)]
    main = main.drop_duplicates(subset=["method", "split"] if "split" in main.columns else ["method"])
    order = {m: k for k, m in enumerate(HEADLINE_METHODS)}
    keys = main["method"].astype(str).map(order)
    splits = main["split"].astype(str).map(lambda s: 0 if s == "heldout" else 1) if "split" in main.columns else keys * 0
    return main.assign(_split_key=splits, _method_key=keys).sort_values(["_split_key", "_method_key"], kind="stable").drop(columns=["_split_key", "_method_key"])


def ladder_rows(metrics_df):
    """Rows of metrics.csv with a learning-ladder ``rung`` (fit, in_distribution, heldout), in rung order; None when there are none."""
    if metrics_df is None or not len(metrics_df) or "rung" not in metrics_df.columns:
        return None
    rung = metrics_df["rung"].astype(object)
    present = rung.notna() & (rung.astype(str).str.strip() != "") & (rung.astype(str) != "nan")
    frame = metrics_df[present]
    if not len(frame):
        return None
    order = {r: k for k, r in enumerate(RUNG_ORDER)}
    keys = frame["rung"].astype(str).map(lambda r: order.get(r, len(order)))
    method_order = {m: k for k, m in enumerate(LADDER_METHOD_ORDER)}
    method_keys = frame["method"].astype(str).map(lambda m: method_order.get(m, len(method_order)))
    frame = frame.assign(_rung_key=keys, _method_key=method_keys)
    return frame.sort_values(["_rung_key", "_method_key"], kind="stable").drop(columns=["_rung_key", "_method_key"])


def format_cell(value) -> str:
    """A cell's text: floats to 3 significant digits (whole above 10⁴), "—" for NaN, "±∞"; anything else escaped."""
    if isinstance(value, (float, np.floating)):
        if np.isinf(value):
            return "∞" if value > 0 else "−∞"
        if not np.isfinite(value):
            return "—"
        return f"{value:.3g}" if abs(value) < 1e4 else f"{value:.0f}"
    return html.escape(str(value))


def number_text(value, digits: int = 1) -> str:
    """A number with ``digits`` decimals; "—" when missing or not finite."""
    try:
        value = float(value)
    except (TypeError, ValueError):
        return "—"
    return f"{value:.{digits}f}" if math.isfinite(value) else "—"


def interval_columns(row, name: str) -> tuple[object, object]:
    """The object-bootstrap interval of a rate when present, else the Wilson one."""
    for kind in ("_boot_ci95", "_ci95"):
        low, high = row.get(f"{name}{kind}_low"), row.get(f"{name}{kind}_high")
        if interval_text(low, high):
            return low, high
    return None, None


def rate_cell(row, name: str, css: str = "") -> str:
    """A rate as "17.5%" in bold with its 95% interval in small type."""
    value = row.get(f"{name}_rate")
    text = percent_text(value)
    if text == "not run":
        return f"<td class='rate na {css}'>not run</td>"
    interval = interval_text(*interval_columns(row, name))
    small = f" <small>({interval})</small>" if interval else ""
    return f"<td class='rate {css}'><b>{text}</b>{small}</td>"


def _grasps_cell(row) -> str:
    n = row.get("n_grasps")
    try:
        n = int(n)
    except (TypeError, ValueError):
        return "<td>—</td>"
    objects = row.get("n_objects")
    text = f"{n}"
    if objects is not None and np.isfinite(float(objects)):
        text += f" on {int(objects)}"
    invalid = row.get("n_invalid")
    if invalid is not None and np.isfinite(float(invalid)) and int(invalid) > 0:
        text += f" ({int(invalid)} invalid)"
    return f"<td>{text}</td>"


def has_lenient(frame) -> bool:
    """Whether the rows carry the lift rate under the write-up's lenient test (evaluate.writeup_protocol)."""
    column = f"{LENIENT}_rate"
    return frame is not None and column in frame.columns and np.isfinite(frame[column].astype(float)).any()


LENIENT_HEADER = "<th class='lenient'>lift, the write-up's test</th>"


def _diversity_cells(row, prefix: str = "") -> list[str]:
    """Distinct held grasps per object and the surface coverage (``prefix`` "filtered_": after the energy filter)."""
    coverage = percent_text(row.get(f"{prefix}surface_coverage_mean"))
    return [f"<td class='diversity'>{number_text(row.get(f'{prefix}distinct_held_per_object_mean'))}</td>",
            f"<td class='diversity'>{coverage if coverage != 'not run' else '—'}</td>"]  # fmt: skip


def cost_text(seconds) -> str:
    """Seconds for a cost cell; "∞" when attempts cost time and gave nothing."""
    try:
        value = float(seconds)
    except (TypeError, ValueError):
        return "—"
    return "∞" if value == math.inf else seconds_text(value)


def _cpu_seconds_cell(row) -> str:
    """CPU-seconds per distinct held grasp, per attempt and after the filter ("5.2 s / 7.1 s")."""
    per_attempt, filtered = (row.get(f"{p}cpu_seconds_per_distinct_held_grasp") for p in ("", "filtered_"))
    return f"<td>{cost_text(per_attempt)} / {cost_text(filtered)}</td>"


def _filtered_rate_cell(row) -> str:
    """The lift rate after the energy filter; "none pass" when no attempt passed, "—" when the filter was not measured."""
    if not _filter_measured(row):
        return "<td class='rate na'>—</td>"
    if is_finite(row.get("filtered_n_grasps")) and int(row["filtered_n_grasps"]) == 0:
        return "<td class='rate na'>none pass</td>"
    return rate_cell(row, "filtered_lift_success")


def _pass_cell(row) -> str:
    """The filter's pass fraction with the passing count ("40.0% (2)"); "—" when the energies were not computed."""
    text = percent_text(row.get("energy_threshold_pass_rate"))
    if text == "not run":
        return "<td>—</td>"
    try:
        return f"<td>{text} <small>({int(row.get('filtered_n_grasps'))})</small></td>"
    except (TypeError, ValueError):
        return f"<td>{text}</td>"


DIVERSITY_HEADERS = "<th class='wrap'>distinct held / object</th><th class='wrap'>surface touched</th>"
FILTER_HEADERS = ("<th class='wrap'>pass the energy filter</th><th class='wrap'>held after the filter: lift test</th>"
                  "<th class='wrap'>after the filter: distinct held / object</th><th class='wrap'>after the filter: surface touched</th>")  # fmt: skip


def measures_table_html(frame) -> str:
    """The wide table below the first screen: readable names, grasps, lift and six-direction rates with intervals, the lift rate beside its
    distinct held grasps per object and surface coverage, per attempt and after the equal energy filter; cost; quality."""
    if frame is None or not len(frame):
        return "<p>No method was evaluated.</p>"
    several_splits = "split" in frame.columns and frame["split"].nunique() > 1
    lenient = has_lenient(frame)
    head = (
        "<tr><th>method</th>" + ("<th>objects</th>" if several_splits else "") + "<th>grasps on objects</th>"
        "<th>held: lift test</th>" + DIVERSITY_HEADERS + "<th>held: six pushes</th>" + (LENIENT_HEADER if lenient else "")
        + FILTER_HEADERS + "<th class='wrap'>CPU s / distinct held grasp (per attempt / filtered)</th><th>penetration (mm)</th>"
        "<th>contact dist. (mm)</th><th>time / grasp</th></tr>"
    )
    body = []
    for _, row in frame.iterrows():
        method = str(row["method"])
        cells = [f"<td class='name'>{html.escape(method_label(method))} <span class='id'>{html.escape(method)}</span></td>"]
        if several_splits:
            cells.append(f"<td>{html.escape(split_label(row['split']))}</td>")
        cells += [_grasps_cell(row), rate_cell(row, "lift_success"), *_diversity_cells(row), rate_cell(row, "six_dir_success")]
        if lenient:
            cells.append(rate_cell(row, LENIENT, "lenient"))
        cells += [_pass_cell(row), _filtered_rate_cell(row), *_diversity_cells(row, "filtered_"), _cpu_seconds_cell(row)]
        cells += [
            f"<td>{number_text(row.get('penetration_mean_mm'))}</td>", f"<td>{number_text(row.get('contact_distance_mean_mm'))}</td>",
            f"<td>{seconds_text(row.get('seconds_per_grasp'))}</td>",
        ]  # fmt: skip
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table class='compact'><thead>{head}</thead><tbody>{''.join(body)}</tbody></table>"


def _ladder_extra_columns(metrics_df, ladder) -> list[str]:
    """Numeric columns only the ladder rows fill (e.g. the fit's pose errors): shown in the ladder table."""
    import pandas as pd

    others = metrics_df.drop(index=ladder.index)
    known = (set(TABLE_COLUMNS) - set(LADDER_COLUMN_LABELS)) | {"rung"}
    extra = []
    for column in [*LADDER_COLUMN_LABELS, *metrics_df.columns]:
        if column not in metrics_df.columns or column in extra:
            continue
        if column in known or column.startswith((LENIENT, "filtered_")) or not pd.api.types.is_numeric_dtype(metrics_df[column]):
            continue
        if ladder[column].notna().any() and (not len(others) or others[column].isna().all()):
            extra.append(column)
    return extra[:4]


def ladder_html(metrics_df) -> str:
    """The learning ladder: fit, in-distribution and held-out rows, each with both rates; empty when not measured."""
    ladder = ladder_rows(metrics_df)
    if ladder is None:
        return ""
    extra = _ladder_extra_columns(metrics_df, ladder)
    lenient = has_lenient(ladder)
    head = (
        "<tr><th>rung</th><th class='name'>method</th><th>grasps on objects</th><th>held: lift test</th>" + DIVERSITY_HEADERS
        + "<th>held: six pushes</th>" + (LENIENT_HEADER if lenient else "") + FILTER_HEADERS
        + "".join(f"<th class='wrap'>{html.escape(LADDER_COLUMN_LABELS.get(c, c.replace('_', ' ')))}</th>" for c in extra) + "</tr>"
    )
    body = []
    previous = None
    rungs = ladder["rung"].astype(str)
    for _, row in ladder.iterrows():
        rung = str(row["rung"])
        cells = []
        if rung != previous:  # one cell for all rows of a rung
            cells.append(f"<td class='name' rowspan='{int((rungs == rung).sum())}'>{html.escape(rung_label(rung))}</td>")
        previous = rung
        method = str(row["method"])
        cells += [f"<td class='name'>{html.escape(method_label(method))} <span class='id'>{html.escape(method)}</span></td>",
                  _grasps_cell(row), rate_cell(row, "lift_success"), *_diversity_cells(row), rate_cell(row, "six_dir_success")]  # fmt: skip
        if lenient:
            cells.append(rate_cell(row, LENIENT, "lenient"))
        cells += [_pass_cell(row), _filtered_rate_cell(row), *_diversity_cells(row, "filtered_")]
        cells += [f"<td>{format_cell(row[c])}</td>" for c in extra]
        body.append("<tr>" + "".join(cells) + "</tr>")
    return (
        "<h2>Learning ladder</h2><p class='note'>Whether the model learned, rung by rung: its own training grasps encoded and "
        "decoded (the originals all held), samples on the objects it was trained on, and samples on objects it never saw. "
        "A rung it fails explains the rungs above it.</p>"
        f"<div class='wide'><table class='compact'><thead>{head}</thead><tbody>{''.join(body)}</tbody></table></div>"
    )


def _in_sentence(label: str) -> str:
    """A method label inside a sentence: "Random start ..." -> "random start ...", acronyms ("CVAE ...") kept."""
    return label[:1].lower() + label[1:] if len(label) > 1 and label[1].islower() else label


def _object_count(row) -> int | None:
    """A metrics row's ``n_objects``, None when absent or NaN."""
    value = row.get("n_objects", math.nan)
    return int(value) if value is not None and math.isfinite(float(value)) else None


def headline_sentence(frame, lift_config: Mapping) -> str:
    """One sentence with the result: the product's two rates and the comparison methods', on the held-out objects."""
    if frame is None or not len(frame):
        return "No method was evaluated in this run."
    split = "heldout" if "split" in frame.columns and (frame["split"].astype(str) == "heldout").any() else (str(frame["split"].iloc[0]) if "split" in frame.columns else "")
    rows = frame[frame["split"].astype(str) == split] if split else frame
    rows = rows.dropna(subset=["lift_success_rate"])
    if not len(rows):
        return "No grasp was simulated in this run."
    lead_method = HEADLINE_METHOD if (rows["method"] == HEADLINE_METHOD).any() else str(rows["method"].iloc[0])
    lead = rows[rows["method"] == lead_method].iloc[0]
    six_run = math.isfinite(float(lead.get("six_dir_success_rate", math.nan)))
    n_objects = _object_count(lead)
    objects = split_label(split)
    if n_objects == 1 and objects.endswith("objects"):
        objects = objects[:-1]
    where = f"On {n_objects} {objects}" if n_objects is not None else f"On the {objects}"
    grasps = f" ({int(lead['n_grasps'])} grasps)" if math.isfinite(float(lead.get("n_grasps", math.nan))) else ""
    if six_run:
        result = (f"{percent_text(lead['lift_success_rate'])} of {method_label(lead_method)} held the object in the lift test and "
                  f"{percent_text(lead['six_dir_success_rate'])} against pushes from all six directions")  # fmt: skip
    else:
        result = f"{percent_text(lead['lift_success_rate'])} of {method_label(lead_method)} held the object in the lift test (six-direction test not run)"
    result += f" per attempt{_diversity_text(lead, '')}{_filter_text(lead)}"
    others = []
    for _, row in rows[rows["method"] != lead_method].iterrows():
        pair = percent_text(row["lift_success_rate"]) + (f" / {percent_text(row['six_dir_success_rate'])}" if six_run else "")
        # a row measured on another number of objects says so (the shipped model samples only objects it never trained on)
        row_objects = _object_count(row)
        on_other_objects = f" (on {row_objects} objects)" if None not in (n_objects, row_objects) and row_objects != n_objects else ""
        after = f", {_filtered_rate_text(row)} after the filter" if _filter_measured(row) else ""
        others.append(f"{_in_sentence(method_label(str(row['method'])))} {pair} per attempt{after}{on_other_objects}")
    tail = f"; for comparison, {'; '.join(others)}" if others else ""
    return f"{where}{grasps}, {result}{tail}."


def _filtered_rate_text(row) -> str:
    """The lift rate after the filter, "none passing" when no attempt passed it."""
    if is_finite(row.get("filtered_n_grasps")) and int(row["filtered_n_grasps"]) == 0:
        return "none passing"
    return percent_text(row.get("filtered_lift_success_rate"))


def is_finite(value) -> bool:
    """Whether ``value`` is a finite number (None, text and NaN are not)."""
    try:
        return value is not None and math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


def _filter_measured(row) -> bool:
    """Whether a metrics row carries the equal energy filter (its pass fraction)."""
    return is_finite(row.get("energy_threshold_pass_rate"))


def _diversity_text(row, prefix: str) -> str:
    """" (2.5 distinct held grasps per object, 31.0% of the surface touched)"; empty when not measured."""
    if not is_finite(row.get(f"{prefix}distinct_held_per_object_mean")):
        return ""
    coverage = row.get(f"{prefix}surface_coverage_mean")
    touched = f", {percent_text(coverage)} of the surface touched" if is_finite(coverage) else ""
    return f" ({number_text(row[f'{prefix}distinct_held_per_object_mean'])} distinct held grasps per object{touched})"


def _filter_text(row) -> str:
    """The lead row after the equal energy filter; empty when the filter was not measured."""
    if not _filter_measured(row):
        return ""
    if is_finite(row.get("filtered_n_grasps")) and int(row["filtered_n_grasps"]) == 0:
        return "; none of its attempts pass the energy filter every method goes through"
    return (f"; after the energy filter every method goes through ({percent_text(row['energy_threshold_pass_rate'])} of attempts pass), "
            f"{_filtered_rate_text(row)} held in the lift test{_diversity_text(row, 'filtered_')}")  # fmt: skip


def full_table_html(metrics_df) -> str:
    """Every column of metrics.csv a reader may want, raw fractions, folded."""
    columns = [c for c in TABLE_COLUMNS if c in metrics_df.columns]
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{format_cell(row[c])}</td>" for c in columns) + "</tr>" for _, row in metrics_df.iterrows())
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"
