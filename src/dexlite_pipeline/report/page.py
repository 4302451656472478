"""The evaluation report: one self-contained HTML page (every image base64-embedded), assembled here
from its parts (``report.first_screen``, ``report.tables``, ``report.plots``, ``report.pictures``) with
the page's own sections and style.

Read from the top, the page answers in this order: the first screen, whole on a 1280 × 900 screen
(``first_screen``: a verdict of at most 40 words naming the recommended way of making grasps on
held-out objects against optimization from scratch, the held-per-attempt chart with the 95%
intervals, and a table of at most seven columns); the run's facts (date, code commit, wall time,
machine); every method's measures: the long result sentence and the wide table (lift and
six-direction rates with their intervals, distinct held grasps per object and surface coverage, per
attempt and after the equal energy filter, the write-up's lenient test, CPU-seconds per distinct
held grasp, time per grasp); the learning ladder when the evaluation measured it; plots (energies,
post-optimization convergence, training curves; success per method again only when several splits
were evaluated); published numbers for context; pictures of grasps drawn at random among each
method's successes and failures, with their contacts marked and the outcome in large type; and last
the run's settings, the physical constants and links to the full CSV tables. It opens from disk, no
server.
"""

from __future__ import annotations

import html
import json
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from dexlite_pipeline.report.families import family_table_html
from dexlite_pipeline.report.first_screen import first_screen_html, first_screen_rows
from dexlite_pipeline.report.grasp_types import grasp_types_html
from dexlite_pipeline.report.inputs import ReportInputs
from dexlite_pipeline.report.pictures import grasp_gallery, interactive_view_html
from dexlite_pipeline.report.plots import budget_plot, convergence_plot, figure_png_base64, histogram_plot, img_tag, success_plot, training_plot
from dexlite_pipeline.report.tables import format_cell, full_table_html, has_lenient, headline_rows, headline_sentence, ladder_html, measures_table_html


# Published numbers a reader compares against: (source, result, how it was measured).
# None of them used this project's test; the last column says what differs.
REFERENCE_ROWS = (
    ("The DexLite write-up (Murali; a lightweight reproduction of Dex1B), raw CVAE samples", "lift success ≈ 55%",
     "its own MuJoCo test (friction 2, lift ratio > 0.7), on its training objects; laptop RTX 4050"),
    ("The DexLite write-up (Murali), CVAE + 200 post-optimization steps", "lift success ≈ 79%; ≈ 2 s per grasp; ≈ 3× faster convergence than random starts",
     "same test and objects"),
    ("Dex1B: Learning with 1B Demonstrations for Dexterous Manipulation", "86.0% with post-optimization and filtering",
     "DexGraspNet benchmark in Isaac Gym, a more lenient test"),
    ("BODex (DexGraspBench: MuJoCo, friction 0.6, six 1 g pushes; the closest protocol to ours)",
     "> 75% success, > 49 grasps/s; learned generators ≈ 40% (trained on DexGraspNet) to ≈ 80% (on BODex data)", "one RTX 3090"),
)  # fmt: skip
# The run's key settings: (label, path in the config). Training steps actually run come from the history.
KEY_SETTINGS = (
    ("seed", ("seed",)),
    ("shards", ("shards",)),
    ("built-in objects requested", ("objects", "builtin_count")),
    ("mesh folders added", ("objects", "mesh_dirs")),
    ("held-out mesh folders", ("objects", "heldout_mesh_dirs")),
    ("held-out fraction", ("objects", "heldout_fraction")),
    ("DexGraspNet root", ("dexgraspnet", "root")),
    ("optimization from scratch: starts per object and scale", ("optimize_grasps", "grasps_per_object")),
    ("optimization from scratch: iterations", ("optimize_grasps", "annealing", "iterations")),
    ("optimization from scratch: scales", ("optimize_grasps", "scales")),
    ("lift: friction", ("lift", "friction")),
    ("lift: object mass (kg)", ("lift", "object_mass_kg")),
    ("lift: finger kp", ("lift", "finger_kp")),
    ("lift: time step (s)", ("lift", "timestep_s")),
    ("lift: success lift ratio", ("lift", "success_lift_ratio")),
    ("training profile", ("train", "profile")),
    ("training steps (max_steps)", ("train", "max_steps")),
    ("training batch size", ("train", "batch_size")),
    ("CVAE syntheses per held-out object", ("sample", "synthesis_grasps_per_object")),
    ("post-optimization iterations", ("post_optimize", "annealing", "iterations")),
    ("post-optimization keep_best", ("post_optimize", "keep_best")),
    ("random-init baseline", ("post_optimize", "random_baseline")),
    ("evaluated splits", ("evaluate", "splits")),
    ("grasps per method and object (at most)", ("evaluate", "grasps_per_object")),
    ("six-direction test", ("evaluate", "six_directions")),
)


def _setting(config: Mapping, path: Sequence[str]):
    """The value at ``path`` in the nested config, or None where a level is missing."""
    value = config
    for key in path:
        if not isinstance(value, Mapping) or key not in value:
            return None
        value = value[key]
    return value


def _setting_text(value) -> str:
    if value is None:
        return "not given"
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, (list, tuple)):
        return ", ".join(map(str, value)) if value else "none"
    if value == "":
        return "none"
    return format_cell(value)


def catalog_counts(objects_dirs: Sequence[str]) -> tuple[dict[str, int], int]:
    """(prepared objects per split, rejected objects) over the catalogs of the objects dirs."""
    from dexlite_pipeline.objects.assets import CATALOG_NAME, read_catalog

    per_split: Counter = Counter()
    rejected = 0
    for directory in objects_dirs:
        if not (Path(directory) / CATALOG_NAME).is_file():
            continue
        catalog = read_catalog(directory)
        ok = catalog["status"].astype(str) == "ok"
        splits = catalog["split"].astype(str) if "split" in catalog.columns else catalog["object_id"].map(lambda _: "unknown")
        per_split.update(splits[ok])
        rejected += int((~ok).sum())
    return dict(per_split), rejected


def training_run_text(history) -> str | None:
    """What training actually ran, from its history: "1,380 steps (69 epochs)"; None without a history."""
    if history is None or not len(history):
        return None
    last = history.iloc[-1]
    parts = []
    if "step" in history.columns and np.isfinite(float(last["step"])):
        parts.append(f"{int(last['step']):,} steps")
    if "epoch" in history.columns and np.isfinite(float(last["epoch"])):
        parts.append(f"{int(last['epoch']):,} epochs")
    if not parts:
        parts.append(f"{len(history):,} history rows")
    return parts[0] + (f" ({parts[1]})" if len(parts) > 1 else "")


def run_settings_html(config: Mapping, objects_dirs: Sequence[str], history=None) -> str:
    """The run's key settings as a table, then the whole config (folded), so a page says how it was made."""
    if not config:
        return "<p>The report was not given the run's config.</p>"
    rows = [(label, _setting_text(_setting(config, path))) for label, path in KEY_SETTINGS]
    ran = training_run_text(history)
    if ran is not None:
        at = next(k for k, (label, _) in enumerate(rows) if label == "training steps (max_steps)") + 1
        rows.insert(at, ("training: steps run", ran))
    per_split, rejected = catalog_counts(objects_dirs)
    if per_split or rejected:
        prepared = ", ".join(f"{n} {split}" for split, n in sorted(per_split.items())) or "none"
        rows.append(("objects prepared (catalogs)", f"{prepared}; {rejected} rejected"))
    body = "".join(f"<tr><td>{html.escape(label)}</td><td>{html.escape(value)}</td></tr>" for label, value in rows)
    whole = html.escape(json.dumps(config, indent=2, sort_keys=True))
    return (
        f"<table><thead><tr><th>setting</th><th>value</th></tr></thead><tbody>{body}</tbody></table>"
        f"<details><summary>whole config</summary><pre>{whole}</pre></details>"
    )


def constants_table_html(lift_config: Mapping) -> str:
    if not lift_config:
        return "<p>The simulated shards carry no lift configuration.</p>"
    rows = "".join(f"<tr><td>{html.escape(str(k))}</td><td>{format_cell(v)}</td></tr>" for k, v in sorted(lift_config.items()))
    return f"<table><thead><tr><th>constant</th><th>value</th></tr></thead><tbody>{rows}</tbody></table>"


STYLE = """
body{font-family:system-ui,sans-serif;margin:1em 2em;max-width:1400px;color:#222}
h1{font-size:22px;margin:0 0 .3em}
p.verdict{font-size:18px;line-height:1.4;max-width:1200px;margin:0 0 .5em}
.glance{display:flex;gap:16px;align-items:flex-start}.glance .chart{flex:0 1 500px;min-width:0}.glance .chart img{width:100%}
.glance .summary{flex:1 1 0;min-width:0}.glance .note{margin:.4em 0 0}
table.summary{font-size:13px;margin:0}table.summary th{vertical-align:bottom;max-width:7.5em}table.summary td{padding:3px 6px}
table.summary th.name,table.summary td.name{text-align:left;max-width:14em}table.summary td.rate{white-space:nowrap}table.summary tr.best td{background:#eaf5ec}
.pick{display:inline-block;font-size:10px;color:#1a7f37;border:1px solid #1a7f37;border-radius:3px;padding:0 3px;margin-left:4px}
div.wide,pre{overflow-x:auto;max-width:100%}div.wide table{width:max-content}h2{font-size:18px;margin:1.4em 0 .4em}h3{font-size:15px}
p.result{font-size:17px;line-height:1.45;max-width:1150px;margin:.3em 0 .6em}
table{border-collapse:collapse;font-size:12px;margin:.6em 0}th,td{border:1px solid #ccc;padding:3px 6px;text-align:right}
th{background:#f0f0f0}td:first-child,th:first-child{text-align:left}
table.compact{font-size:14px}table.compact td,table.compact th{padding:4px 8px}table.compact td.name{text-align:left}
table.compact td.name .id{display:block}
table.compact th{white-space:nowrap}table.compact th.wrap{white-space:normal;max-width:9em}table.compact th.name{text-align:left}
td.rate b{font-size:15px}td.rate small{color:#555}td.na{color:#888}td.lenient,th.lenient{color:#666;background:#fafafa}
td.lenient b{font-size:13px;font-weight:600}.id{color:#888;font-size:11px;font-family:monospace}
table.text td,table.text th{text-align:left;max-width:34em}
.gallery{display:flex;flex-wrap:wrap;gap:10px}figure{margin:0;border:1px solid #ddd;padding:4px;width:300px}
figcaption{font-size:11px;color:#444}img{max-width:100%}.note{font-size:12px;color:#555;max-width:1150px}
.outcome{font-size:24px;font-weight:700;letter-spacing:.02em}.held{color:#1a7f37}.partial{color:#b35c00}.dropped{color:#c62828}
.detail{font-size:12px;color:#333}.facts{font-size:11px;color:#666}table.facts td{text-align:left;border:none;padding:1px 8px 1px 0}
"""


def convergence_note(metrics_df, curves) -> str:
    """One sentence: at which iteration CVAE starts reach the random-init baseline's final median E_post."""
    if curves is None or not len(curves) or not len(metrics_df) or "iterations_to_random_final_E_post" not in metrics_df:
        return ""
    rows = metrics_df.drop_duplicates("method").set_index("method")
    if not {"cvae_post", "random_post"} <= set(rows.index):
        return ""
    budget = curves.loc[curves["method"] == "random_post", "iteration"].max()
    reached = rows.loc["cvae_post", "iterations_to_random_final_E_post"]
    if not np.isfinite(reached):
        return f"<p class='note'>CVAE starts do not reach the random-init baseline's final median E_post within {int(budget)} iterations.</p>"
    speedup = f"{budget / reached:.1f}×" if reached > 0 else "already at the start (iteration 0)"
    return (
        f"<p class='note'>CVAE starts reach the median E_post that random starts end with after {int(budget)} iterations "
        f"at iteration {int(reached)}: speed-up {speedup} (the write-up reports ≈ 3×).</p>"
    )


def definitions_html(lift_config: Mapping) -> str:
    def constant(key: str, scale: float = 1.0) -> str:
        value = lift_config.get(key)
        return format_cell(float(value) * scale) if isinstance(value, (int, float)) else "?"

    return (
        f"<p class='note'>Lift test: the hand closes on the object and rises {constant('lift_height_m')} m; a grasp holds when the "
        f"object rises with it (lift ratio &gt; {constant('success_lift_ratio')}). Six-direction test: from a fresh start each "
        f"time and without gravity, a force of {constant('six_dir_force_per_kg_n')} N per kg of the object's mass along ±x, ±y and "
        f"±z in turn, {constant('six_dir_duration_s')} s each; a grasp holds when the object moves less than "
        f"{constant('six_dir_max_translation_m', 100)} cm and turns less than {constant('six_dir_max_rotation_deg')}° in all six. "
        "The two rates carry equal weight: "
        "a lift alone can be a palm-up carry. Rates are fractions of the evaluated grasps; n_invalid of the n_grasps had no usable "
        "pose or scale, were not simulated and count as failures. object_success_rate: share of objects with at least one lifted "
        "grasp. Joint entropy: mean per-joint histogram entropy in bits (bins over each joint's range, as in DexGraspNet); PCA: "
        "cumulative explained variance of the 22 joint angles (lower = more diverse); held_joint_entropy_bits: the same over the held "
        "grasps. Distinct held grasps: held grasps of an object and scale are one grasp when their palms are within "
        "diversity.distinct_translation_m and diversity.distinct_rotation_deg (greedy clustering), summed over scales; per object "
        "= mean over the row's objects, per attempt = total over n_grasps. Surface touched (surface_coverage_mean): per object, the "
        "share of its surface patches (diversity.coverage_patches, about equal area) that a contact candidate of a held grasp "
        "touches (within diversity.coverage_contact_m), averaged over objects. Equal filter: every method is counted per attempt "
        "and after the same energy thresholds (evaluate.filter_thresholds) on the evaluation's own energies; "
        "energy_threshold_pass_rate = passing attempts / attempts, filtered_* = the measures on the passing grasps only. "
        "seconds_per_grasp sums the stages that made the method's grasps, per attempt, on this machine (one-thread jobs: "
        "CPU-seconds on a CPU run; training, preparation and the evaluation itself not included); cpu_seconds_per_held_grasp "
        "and cpu_seconds_per_distinct_held_grasp divide all attempts' seconds by the held (distinct held) grasps they gave. "
        "cvae_raw, cvae_post and random_post are evaluated on the same sampled rows (same "
        "objects and scales). Intervals: ci95 = Wilson (grasps taken as independent); boot_ci95 = object-level bootstrap "
        "(objects resampled with replacement: wider when success depends on the object, rough with few objects), the one the "
        "tables and the error bars show.</p>"
    )


def run_facts_html(facts: Sequence[tuple[str, str]]) -> str:
    """The run's date, code commit, wall time and machine as one small line-per-fact table."""
    if not facts:
        return ""
    rows = "".join(f"<tr><td>{html.escape(label)}</td><td>{html.escape(value)}</td></tr>" for label, value in facts)
    return f"<table class='facts'><tbody>{rows}</tbody></table>"


def csv_links_html(links: Mapping[str, str]) -> str:
    if not links:
        return ""
    items = " · ".join(f"<a href='{html.escape(href)}'>{html.escape(name)}</a>" for name, href in links.items())
    return f"<p>Full tables: {items}</p>"


def learning_curve_html(curve) -> str:
    """The shipped model's learning curve (docs/learning_curve.csv, made on its run): plot and table."""
    from dexlite_pipeline.report.learning_curve import curve_figure

    columns = ["point", "seed", "training_objects", "training_grasps", "method", "n_grasps", "lift_success_rate", "lift_success_ci95_low",
               "lift_success_ci95_high", "six_dir_success_rate", "seconds_per_grasp"]  # fmt: skip
    table = curve[[c for c in columns if c in curve.columns]].to_html(index=False, float_format=lambda v: f"{v:.3g}", na_rep="—")
    return (
        "<h2>Learning curve of the shipped model's run</h2><p class='note'>Success on the held-out objects of the shipped model's run "
        "against the number of training objects (nested subsets of that run's training objects, same sampling and post-optimization "
        "budget; Wilson 95%). From docs/learning_curve.csv of this checkout: it describes the shipped model's training, not this "
        "run's; docs/learning_curve.md has it per held-out split and against grasps per object.</p>"
        + img_tag(figure_png_base64(curve_figure(curve)), "learning curve") + f"<details><summary>table</summary><div class='wide'>{table}</div></details>"
    )


DATA_LOOP_COLUMNS = {
    "round": "round", "grasps_per_object": "grasps / training object", "distinct_per_object": "distinct / training object",
    "distinct_min": "fewest distinct", "objects_without_grasps": "objects without grasps", "kept": "new kept", "sampled": "sampled",
    "cpu_minutes": "CPU min", "heldout_lift_success": "held-out lift", "heldout_six_dir_success": "held-out six pushes",
    "heldout_distinct_per_object": "distinct held / held-out object",
}  # fmt: skip


def data_loop_html(table) -> str:
    """The data loop's rounds: the training set's growth, what each round cost and how its model does on held-out objects."""
    shown = table.assign(cpu_minutes=table["cpu_seconds"] / 60.0)
    reasons = [c for c in ("not_optimized", "energy_filter", "lift_test", "six_directions", "duplicate") if c in shown.columns]
    shown = shown.assign(dropped=[", ".join(f"{r} {int(row[r])}" for r in reasons if row[r]) or "–" for _, row in shown.iterrows()])
    columns = {**DATA_LOOP_COLUMNS, "dropped": "dropped (why)"}
    body = shown[[c for c in columns if c in shown.columns]].rename(columns=columns).to_html(
        index=False, float_format=lambda v: f"{v:.3g}", na_rep="–"
    )
    return (
        "<h2>Data loop</h2><p class='note'>Round 0 is the model trained on the pipeline's own grasps; each later round samples "
        "grasps on every training object with the previous round's model (debiased associated points), post-optimizes them, keeps "
        "those that pass the energy filter, the lift test and the six pushes and are new distinct grasps (2 cm / 30°), and trains "
        "the next model on the grown set, warm-started. Held-out columns: a small check of each round's model on the held-out "
        "objects (sampled, post-optimized, lift-tested; per attempt), not the evaluation above, which uses the last round's model. "
        "CPU minutes: the round's jobs (round 0: made by the stages before the loop). Per object: results/round_&lt;r&gt;/summary.csv.</p>"
        + f"<div class='wide'>{body}</div>"
    )


def measures_section_html(headline, lift_config: Mapping) -> str:
    """Every main method's measures, below the first screen: the long result sentence, the wide table (it scrolls
    sideways on its own, so the page never gets wider than the screen) and the key to its columns."""
    lenient = (
        "; “lift, the write-up's test”: the same grasps under the more lenient lift test of the DexLite write-up (Murali) "
        "(Wilson interval), for comparison with its published numbers" if has_lenient(headline) else ""
    )
    return (
        "<h2>Every method, every measure</h2>"
        f"<p class='result'>{html.escape(headline_sentence(headline, lift_config))}</p>"
        f"<div class='wide'>{measures_table_html(headline)}</div>"
        "<p class='note'>Both tests count with equal weight: “lift test” = the object rose with the hand; "
        "“six pushes” = it stayed put under a push of about its own weight along each of ±x, ±y, ±z in turn. "
        f"Small numbers: object-level bootstrap 95% interval (objects resampled){lenient}. Definitions and every column: end of the page.</p>"
    )


def plot_sections_html(inputs: ReportInputs, several_splits: bool) -> list[str]:
    """The plots' sections; success per method only when several splits were evaluated (the first screen shows one split)."""
    sections = []
    for title, image in (
        ("Success per method, every split", success_plot(inputs.metrics) if several_splits else None),
        ("Energies and penetration", histogram_plot(inputs.simulated)),
        ("Post-optimization convergence (median, interquartile band)", convergence_plot(inputs.convergence)),
        ("Lift success against the post-optimization budget (Wilson 95% band)", budget_plot(inputs.budget)),
        ("CVAE training curves", training_plot(inputs.history)),
    ):
        if image is None and title.startswith(("Lift success against", "Success per method")):
            continue  # only runs that lift-test post-optimization budgets, or evaluate several splits, have these plots
        sections.append(f"<h2>{html.escape(title)}</h2>" + (img_tag(image, title) if image else "<p>Not available in this run.</p>"))
        if title.startswith("Post-optimization convergence"):
            sections.append(convergence_note(inputs.metrics, inputs.convergence))
    return sections


def build_report_html(inputs: ReportInputs) -> str:
    """The whole page as a string: the first screen, then the run, every measure, the ladder, plots, pictures and settings."""
    headline = headline_rows(inputs.metrics)
    first_rows = first_screen_rows(inputs.metrics)
    several_splits = headline is not None and first_rows is not None and len(headline) > len(first_rows)
    sections = [f"<h1>{html.escape(inputs.title)}</h1>", first_screen_html(inputs.metrics)]
    if inputs.run_facts:
        sections.append("<h2>The run</h2>" + run_facts_html(inputs.run_facts))
    sections.append(measures_section_html(headline, inputs.lift_config))
    sections.append(ladder_html(inputs.metrics))
    types = grasp_types_html(inputs.simulated, inputs.config)  # only when the grasps hold several types
    if types:
        sections.append(types)
    sections += plot_sections_html(inputs, several_splits)
    if inputs.data_loop is not None and len(inputs.data_loop):
        sections.append(data_loop_html(inputs.data_loop))
    if inputs.learning_curve is not None and len(inputs.learning_curve):
        sections.append(learning_curve_html(inputs.learning_curve))
    ref_rows = "".join(f"<tr><td>{html.escape(a)}</td><td>{html.escape(b)}</td><td>{html.escape(c)}</td></tr>" for a, b, c in REFERENCE_ROWS)
    sections.append(
        "<h2>Published numbers, for context</h2><p class='note'>Measured with other tests and other data: none of them is "
        "directly comparable with the rates above.</p>"
        f"<table class='text'><thead><tr><th>source</th><th>result</th><th>how measured</th></tr></thead><tbody>{ref_rows}</tbody></table>"
    )
    sections.append(
        "<h2>Grasps, drawn at random</h2><p class='note'>For each method, grasps drawn at random (seeded) among those that passed "
        "the lift test and those that failed it; two viewpoints each; red dots: the four contact points nearest the surface.</p>"
        + grasp_gallery(inputs)
    )
    sections.append(
        "<h2>The same grasps in 3-D</h2><p class='note'>Drag to turn, scroll to zoom; the slider shows one grasp at a time, "
        "titled with its method and results.</p>" + interactive_view_html(inputs)
    )
    by_family = family_table_html(inputs.metrics, inputs.per_object)
    if by_family:
        sections.append(
            "<h2>By family</h2><p class='note'>The held-out objects grouped by family (a generated object's family, its "
            "perturbed instances with it; <i>procedural</i>: pybullet_data's procedural objects; <i>other</i>: the rest), "
            "per method: where a method holds and where it does not.</p>" + by_family
        )
    if inputs.per_object is not None and len(inputs.per_object):
        per_object = inputs.per_object.to_html(index=False, float_format=lambda v: f"{v:.3g}", na_rep="—")
        sections.append(f"<h2>Per object</h2><details><summary>{len(inputs.per_object)} rows</summary><div class='wide'>{per_object}</div></details>")
    sections.append("<h2>Run settings</h2>" + run_settings_html(inputs.config, inputs.objects_dirs, inputs.history))
    sections.append("<h2>Physical constants of the lift and six-direction tests</h2>" + constants_table_html(inputs.lift_config))
    sections.append(
        "<h2>All numbers</h2>" + csv_links_html(inputs.csv_links) + definitions_html(inputs.lift_config)
        + "<details><summary>metrics.csv, every method and column</summary><div class='wide'>" + full_table_html(inputs.metrics) + "</div></details>"
    )  # fmt: skip
    return f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(inputs.title)}</title><style>{STYLE}</style></head><body>{''.join(sections)}</body></html>"
