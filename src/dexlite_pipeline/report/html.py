"""The evaluation report: one self-contained HTML page (every image base64-embedded).

Sections: the run's key settings (and its whole config), the metrics table beside the
published reference numbers, success rates per method, energy and penetration histograms,
post-optimization convergence curves, CVAE training curves, the physical constants of the
simulation, and pictures of successful and failed grasps of every method from two
viewpoints. It opens from disk, no server.
"""

from __future__ import annotations

import base64
import html
import io
import json
import logging
import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.report.metrics import invalid_flags

log = logging.getLogger(__name__)

# Published numbers a reader compares against (DESIGN.md, "Reference results to beat").
REFERENCE_ROWS = (
    ("DexLite seed paper, raw CVAE samples", "lift success ≈ 55%", "RTX 4050 laptop GPU"),
    ("DexLite seed paper, CVAE + 200 post-optimization steps", "lift success ≈ 79%; ≈ 2 s per grasp", "RTX 4050 laptop GPU"),
    ("DexLite seed paper, CVAE init vs random init", "≈ 3× faster convergence", ""),
    ("DexLite seed paper, curated DexGraspNet grasps", "≈ 90% pass lift", ""),
    ("BODex", "> 49 grasps/s; > 75% simulated success", "one RTX 3090"),
)
TABLE_COLUMNS = (
    "method", "split", "n_grasps", "n_invalid", "n_objects", "lift_success_rate", "lift_success_ci95_low", "lift_success_ci95_high",
    "lift_success_boot_ci95_low", "lift_success_boot_ci95_high", "object_success_rate", "six_dir_success_rate",
    "six_dir_success_ci95_low", "six_dir_success_ci95_high", "six_dir_success_boot_ci95_low", "six_dir_success_boot_ci95_high",
    "penetration_mean_mm", "penetration_p95_mm", "contact_distance_mean_mm", "E_fc_mean", "energy_threshold_pass_rate",
    "joint_entropy_bits", "pca_explained_variance_k1", "pca_explained_variance_k3", "seconds_per_grasp",
    "E_post_median_final", "iterations_to_random_final_E_post", "threshold_reached_fraction",
)  # fmt: skip
HISTOGRAMS = (("E_fc", "E_fc"), ("penetration_mm", "penetration (mm)"), ("contact_distance_mm", "contact distance (mm)"))
SUCCESS_BARS = (("lift_success_rate", "lift (per grasp)"), ("object_success_rate", "lift (per object)"), ("six_dir_success_rate", "six directions"))
# The run's key settings: (label, path in the config).
KEY_SETTINGS = (
    ("seed", ("seed",)),
    ("shards", ("shards",)),
    ("built-in objects requested", ("objects", "builtin_count")),
    ("mesh folders added", ("objects", "mesh_dirs")),
    ("held-out mesh folders", ("objects", "heldout_mesh_dirs")),
    ("held-out fraction", ("objects", "heldout_fraction")),
    ("DexGraspNet root", ("dexgraspnet", "root")),
    ("seed synthesis: starts per object and scale", ("seed_grasps", "grasps_per_object")),
    ("seed synthesis: iterations", ("seed_grasps", "annealing", "iterations")),
    ("seed synthesis: scales", ("seed_grasps", "scales")),
    ("lift: friction", ("lift", "friction")),
    ("lift: object mass (kg)", ("lift", "object_mass_kg")),
    ("lift: finger kp", ("lift", "finger_kp")),
    ("lift: time step (s)", ("lift", "timestep_s")),
    ("lift: success lift ratio", ("lift", "success_lift_ratio")),
    ("training profile", ("train", "profile")),
    ("training steps (max_steps)", ("train", "max_steps")),
    ("training epochs", ("train", "epochs")),
    ("training batch size", ("train", "batch_size")),
    ("CVAE syntheses per held-out object", ("sample", "synthesis_grasps_per_object")),
    ("post-optimization iterations", ("post_optimize", "iterations")),
    ("post-optimization keep_best", ("post_optimize", "keep_best")),
    ("random-init baseline", ("post_optimize", "random_baseline")),
    ("evaluated splits", ("evaluate", "splits")),
    ("grasps per method and object (at most)", ("evaluate", "grasps_per_object")),
    ("six-direction test", ("evaluate", "six_directions")),
)


@dataclass
class ReportInputs:
    """Everything the page shows; frames are pandas DataFrames (may be empty)."""

    metrics: object
    per_object: object
    convergence: object
    history: object | None
    simulated: GraspSet | None
    lift_config: Mapping = field(default_factory=dict)
    objects_dirs: Sequence[str] = ()
    rendered_per_method: int = 2
    config: Mapping = field(default_factory=dict)  # the whole run config, shown in the page
    title: str = "DexLite evaluation"


def figure_png_base64(fig) -> str:
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _img(data_b64: str, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data_b64}">'


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def success_figure(metrics_df):
    """Grouped bars: lift, object and six-direction success per method; error bars are the object-bootstrap 95% intervals.

    A rate that was not measured (NaN, e.g. the six-direction test switched off) gets no
    bar and a "not run" mark, never a bar at 0%. None when no method has a lift rate.
    """
    frame = metrics_df.dropna(subset=["lift_success_rate"]) if len(metrics_df) else metrics_df
    if not len(frame):
        return None
    plt = _plt()
    from matplotlib.patches import Patch

    labels = [f"{m}\n({s})" for m, s in zip(frame["method"], frame["split"])]
    x = np.arange(len(frame))
    fig, ax = plt.subplots(figsize=(max(5, 1.3 * len(frame)), 3.4))
    width = 0.8 / len(SUCCESS_BARS)
    not_run = []
    for k, (column, name) in enumerate(SUCCESS_BARS):
        values = frame[column].astype(float).to_numpy() * 100 if column in frame.columns else np.full(len(frame), np.nan)
        measured = np.isfinite(values)
        positions = x + (k - 1) * width
        interval = column.replace("_rate", "_boot_ci95")
        error = None
        if f"{interval}_low" in frame.columns:
            low = frame[f"{interval}_low"].astype(float).to_numpy() * 100
            high = frame[f"{interval}_high"].astype(float).to_numpy() * 100
            error = np.nan_to_num(np.stack([values - low, high - values])[:, measured], nan=0.0)
        if measured.any():
            ax.bar(positions[measured], values[measured], width, color=f"C{k}", label=name, yerr=error, capsize=2, error_kw={"lw": 0.8})
        else:
            not_run.append(Patch(facecolor="none", edgecolor=f"C{k}", label=f"{name} (not run)"))
        for position in positions[~measured]:
            ax.text(position, 1, "not run", rotation=90, fontsize=6, ha="center", va="bottom", color="grey")
    ax.axhline(79, color="grey", ls="--", lw=0.8)
    ax.text(x[-1] + 0.45, 79, "seed paper post-opt 79%", fontsize=7, va="bottom", ha="right", color="grey")
    ax.set_xticks(x, labels, fontsize=8)
    ax.set_ylabel("success (%)")
    ax.set_ylim(0, 100)
    ax.set_title("error bars: object-level bootstrap 95% interval (objects resampled)", fontsize=8)
    ax.legend(handles=ax.get_legend_handles_labels()[0] + not_run, fontsize=7, loc="upper left")
    return fig


def success_plot(metrics_df) -> str | None:
    """The success bars as base64 PNG (None when there is nothing to show)."""
    fig = success_figure(metrics_df)
    return figure_png_base64(fig) if fig is not None else None


def histogram_plot(simulated: GraspSet | None) -> str | None:
    """Per-method histograms of E_fc, penetration and contact distance."""
    if simulated is None or len(simulated) == 0 or "method" not in simulated.arrays:
        return None
    present = [(k, label) for k, label in HISTOGRAMS if k in simulated.arrays]
    if not present:
        return None
    plt = _plt()
    methods = np.asarray([str(m) for m in simulated.arrays["method"]])
    fig, axes = plt.subplots(1, len(present), figsize=(4.2 * len(present), 3.0))
    axes = np.atleast_1d(axes)
    for ax, (key, label) in zip(axes, present):
        values = np.asarray(simulated.arrays[key], dtype=np.float64)
        finite = values[np.isfinite(values)]
        if finite.size == 0:
            ax.set_title(f"{label}: not computed", fontsize=9)
            continue
        hi = float(np.percentile(finite, 99)) or 1.0
        bins = np.linspace(float(finite.min()), hi, 30)
        for method in dict.fromkeys(methods):
            v = values[(methods == method) & np.isfinite(values)]
            if v.size:
                ax.hist(np.clip(v, bins[0], bins[-1]), bins=bins, histtype="step", lw=1.4, label=method, density=True)
        ax.set_xlabel(label)
        ax.set_ylabel("density")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    return figure_png_base64(fig)


def convergence_plot(curves) -> str | None:
    """Median and interquartile band of E_post per iteration for each post-optimized method."""
    if curves is None or not len(curves):
        return None
    energy = "E_post" if (curves["energy"] == "E_post").any() else str(curves["energy"].iloc[0])
    frame = curves[curves["energy"] == energy]
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.5, 3.2))
    for method, group in frame.groupby("method"):
        group = group.sort_values("iteration")
        line = ax.plot(group["iteration"], group["median"], label=f"{method} (median)")[0]
        ax.fill_between(group["iteration"], group["q25"], group["q75"], color=line.get_color(), alpha=0.2)
    if (frame[["q25", "median", "q75"]].to_numpy() > 0).all():
        ax.set_yscale("log")
    ax.set_xlabel("post-optimization iteration")
    ax.set_ylabel(energy)
    ax.legend(fontsize=7)
    return figure_png_base64(fig)


def training_plot(history) -> str | None:
    """CVAE training history: one panel per loss term, training and validation curves together, against the step."""
    if history is None or not len(history):
        return None
    x_name = next((c for c in ("step", "epoch", "iteration") if c in history.columns), None)
    x = history[x_name] if x_name else np.arange(len(history))
    bookkeeping = {"step", "epoch", "iteration", "seconds", "time_s", "seconds_elapsed"}
    numeric = [c for c in history.columns if c not in bookkeeping and np.issubdtype(history[c].dtype, np.number)]
    panels: dict[str, list[str]] = {}
    for name in numeric:
        term = name.split("_", 1)[1] if name.startswith(("train_", "val_")) else name
        panels.setdefault(term, []).append(name)
    if not panels:
        return None
    plt = _plt()
    cols = min(4, len(panels))
    rows = math.ceil(len(panels) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.4 * rows), squeeze=False)
    for ax, (term, names) in zip(axes.ravel(), panels.items()):
        for name in names:
            values = history[name].astype(float)
            ax.plot(x, values, lw=1, label=name.split("_", 1)[0] if name != term else name)
        finite = history[names].astype(float).stack().dropna()
        if len(finite) and (finite > 0).all() and finite.max() / max(finite.min(), 1e-12) > 50:
            ax.set_yscale("log")
        ax.set_title(term, fontsize=8)
        ax.tick_params(labelsize=7)
        if len(names) > 1:
            ax.legend(fontsize=6)
    for ax in axes.ravel()[len(panels) :]:
        ax.set_axis_off()
    for ax in axes[-1]:
        ax.set_xlabel(x_name or "row", fontsize=7)
    fig.tight_layout()
    return figure_png_base64(fig)


def pick_examples(simulated: GraspSet, method: str, count: int) -> list[tuple[int, bool]]:
    """Up to ``count`` lift successes and ``count`` failures of a method (rows, success flag), spread over objects.

    Invalid grasps (no usable pose, not simulated) are not pictured.
    """
    methods = np.asarray([str(m) for m in simulated.arrays["method"]])
    success = np.asarray(simulated.arrays.get("lift_success", np.zeros(len(simulated), bool)), dtype=bool)
    object_ids = np.asarray([str(o) for o in simulated.object_id])
    picturable = ~invalid_flags(simulated.arrays)
    picks = []
    for outcome in (True, False):
        rows = np.nonzero((methods == method) & (success == outcome) & picturable)[0]
        # one per object first (sorted objects), then the rest in row order
        firsts = [int(rows[object_ids[rows] == o][0]) for o in sorted(set(object_ids[rows]))]
        ordered = firsts + [int(r) for r in rows if int(r) not in set(firsts)]
        picks += [(r, outcome) for r in ordered[:count]]
    return picks


def grasp_gallery(inputs: ReportInputs) -> str:
    """HTML of rendered successes and failures for each method."""
    simulated = inputs.simulated
    if simulated is None or len(simulated) == 0 or inputs.rendered_per_method == 0:
        return "<p>No simulated grasps to picture.</p>"
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.report.render import render_grasp_png

    hand = ShadowHand()
    present = set(str(m) for m in simulated.arrays["method"])
    table_order = list(dict.fromkeys(inputs.metrics["method"])) if len(inputs.metrics) else []
    methods = [m for m in table_order if m in present] + sorted(present - set(table_order))
    parts = []
    for method in methods:
        cells = []
        for row, success in pick_examples(simulated, method, inputs.rendered_per_method):
            object_id, scale = str(simulated.object_id[row]), float(simulated.scale[row])
            caption = f"{'success' if success else 'failure'} · {object_id} · scale {scale:.3f}"
            reason = str(simulated.arrays["failure_reason"][row]) if "failure_reason" in simulated.arrays else ""
            if reason and not success:
                caption += f" · {reason}"
            if "penetration_mm" in simulated.arrays and np.isfinite(simulated.arrays["penetration_mm"][row]):
                caption += f" · pen {float(simulated.arrays['penetration_mm'][row]):.1f} mm"
            try:
                png = render_grasp_png(hand, simulated.hand_pose[row], object_id, scale, inputs.objects_dirs, size_px=260)
            except (ValueError, OSError) as exc:
                log.warning("report: cannot render %s row %d: %s", method, row, exc)
                cells.append(f"<figure><figcaption>{html.escape(caption)} — not rendered: {html.escape(str(exc))}</figcaption></figure>")
                continue
            cells.append(f"<figure>{_img(base64.b64encode(png).decode('ascii'), caption)}<figcaption>{html.escape(caption)}</figcaption></figure>")
        parts.append(f"<h3>{html.escape(method)}</h3><div class='gallery'>{''.join(cells) or '<p>none</p>'}</div>")
    return "".join(parts)


def _format(value) -> str:
    if isinstance(value, (float, np.floating)):
        if np.isinf(value):
            return "∞" if value > 0 else "−∞"
        if not np.isfinite(value):
            return "—"
        return f"{value:.3g}" if abs(value) < 1e4 else f"{value:.0f}"
    return html.escape(str(value))


def metrics_table_html(metrics_df) -> str:
    columns = [c for c in TABLE_COLUMNS if c in metrics_df.columns]
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{_format(row[c])}</td>" for c in columns) + "</tr>" for _, row in metrics_df.iterrows())
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


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
    return _format(value)


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


def run_settings_html(config: Mapping, objects_dirs: Sequence[str]) -> str:
    """The run's key settings as a table, then the whole config (folded), so a page says how it was made."""
    if not config:
        return "<p>The report was not given the run's config.</p>"
    rows = [(label, _setting_text(_setting(config, path))) for label, path in KEY_SETTINGS]
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
    rows = "".join(f"<tr><td>{html.escape(str(k))}</td><td>{_format(v)}</td></tr>" for k, v in sorted(lift_config.items()))
    return f"<table><thead><tr><th>constant</th><th>value</th></tr></thead><tbody>{rows}</tbody></table>"


STYLE = """
body{font-family:system-ui,sans-serif;margin:2em;max-width:1400px;color:#222}
table{border-collapse:collapse;font-size:12px;margin:1em 0}th,td{border:1px solid #ccc;padding:3px 6px;text-align:right}
th{background:#f0f0f0}td:first-child,th:first-child{text-align:left}
.gallery{display:flex;flex-wrap:wrap;gap:8px}figure{margin:0;border:1px solid #ddd;padding:4px;max-width:540px}
figcaption{font-size:11px;color:#444}img{max-width:100%}.note{font-size:12px;color:#555}
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
        f"at iteration {int(reached)}: speed-up {speedup} (seed paper: ≈ 3×).</p>"
    )


def build_report_html(inputs: ReportInputs) -> str:
    """The whole page as a string."""
    sections = [f"<h1>{html.escape(inputs.title)}</h1>"]
    sections.append(
        "<p class='note'>Rates are fractions of simulated grasps (lift: object rises with the hand, ratio &gt; "
        f"{_format(inputs.lift_config.get('success_lift_ratio', math.nan))}); per-object success = at least one successful grasp. "
        "Joint entropy: DexGraspNet's mean per-joint histogram entropy in bits (bins over each joint's range); "
        "PCA: cumulative explained variance of the 22 joint angles (DexGraspBench; lower = more diverse). "
        "seconds_per_grasp sums the stages that made the method's grasps on this machine. "
        "n_invalid of the n_grasps had no usable pose or scale: they were not simulated and count as failures. "
        "cvae_raw, cvae_post and random_post are evaluated on the same sampled rows (same objects and scales). "
        "Intervals: ci95 = Wilson (grasps taken as independent); boot_ci95 = object-level bootstrap "
        "(objects resampled with replacement: wider when success depends on the object, rough with few objects), "
        "used for the error bars.</p>"
    )
    sections.append("<h2>Run settings</h2>" + run_settings_html(inputs.config, inputs.objects_dirs))
    sections.append("<h2>Metrics</h2>" + metrics_table_html(inputs.metrics))
    ref_rows = "".join(f"<tr><td>{html.escape(a)}</td><td>{html.escape(b)}</td><td>{html.escape(c)}</td></tr>" for a, b, c in REFERENCE_ROWS)
    sections.append(f"<h2>Reference numbers</h2><table><thead><tr><th>source</th><th>result</th><th>hardware</th></tr></thead><tbody>{ref_rows}</tbody></table>")
    for title, image in (
        ("Success per method (error bars: object-level bootstrap 95% interval)", success_plot(inputs.metrics)),
        ("Energies and penetration", histogram_plot(inputs.simulated)),
        ("Post-optimization convergence (median, interquartile band)", convergence_plot(inputs.convergence)),
        ("CVAE training curves", training_plot(inputs.history)),
    ):
        sections.append(f"<h2>{html.escape(title)}</h2>" + (_img(image, title) if image else "<p>Not available in this run.</p>"))
        if title.startswith("Post-optimization convergence"):
            sections.append(convergence_note(inputs.metrics, inputs.convergence))
    sections.append("<h2>Physical constants of the lift and six-direction tests</h2>" + constants_table_html(inputs.lift_config))
    if inputs.per_object is not None and len(inputs.per_object):
        sections.append("<h2>Per object</h2>" + inputs.per_object.to_html(index=False, float_format=lambda v: f"{v:.3g}", na_rep="—"))
    sections.append("<h2>Grasps (two viewpoints each)</h2>" + grasp_gallery(inputs))
    return f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(inputs.title)}</title><style>{STYLE}</style></head><body>{''.join(sections)}</body></html>"
