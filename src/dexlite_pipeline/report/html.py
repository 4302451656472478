"""The evaluation report: one self-contained HTML page (every image base64-embedded).

Read from the top, the page answers in this order: the run's facts (date, code commit, wall
time, machine); one sentence with the result and a compact table (readable method names,
lift and six-direction rates side by side with their 95% intervals, the lift rate beside
the distinct held grasps per object and the surface coverage, per attempt and after the
equal energy filter, and the CPU-seconds per distinct held grasp); the learning ladder
when the evaluation measured it; plots (success per method, energies, post-optimization
convergence, training curves); published numbers for context; pictures of grasps drawn at
random among each method's successes and failures, with their contacts marked and the
outcome in large type; and last the run's settings, the physical constants and links to
the full CSV tables. It opens from disk, no server.
"""

from __future__ import annotations

import base64
import html
import io
import json
import logging
import math
import zlib
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.evaluation.metrics import (
    interval_text, invalid_flags, method_label, percent_text, rung_label, seconds_text, split_label,
)  # fmt: skip

log = logging.getLogger(__name__)

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
# Every column of metrics.csv worth a reader's look, for the folded full table at the end.
TABLE_COLUMNS = (
    "method", "split", "rung", "n_grasps", "n_invalid", "n_objects", "lift_success_rate", "lift_success_ci95_low", "lift_success_ci95_high",
    "lift_success_boot_ci95_low", "lift_success_boot_ci95_high", "object_success_rate", "six_dir_success_rate",
    "six_dir_success_ci95_low", "six_dir_success_ci95_high", "six_dir_success_boot_ci95_low", "six_dir_success_boot_ci95_high",
    "penetration_mean_mm", "penetration_p95_mm", "contact_distance_mean_mm", "E_fc_mean", "energy_threshold_pass_rate",
    "joint_entropy_bits", "held_joint_entropy_bits", "pca_explained_variance_k1", "pca_explained_variance_k3",
    "n_held", "distinct_held_total", "distinct_held_per_object_mean", "distinct_held_per_attempt", "surface_coverage_mean",
    "filtered_n_grasps", "filtered_lift_success_rate", "filtered_lift_success_ci95_low", "filtered_lift_success_ci95_high",
    "filtered_six_dir_success_rate", "filtered_n_held", "filtered_distinct_held_total", "filtered_distinct_held_per_object_mean",
    "filtered_distinct_held_per_attempt", "filtered_surface_coverage_mean", "seconds_per_grasp", "cpu_seconds_per_held_grasp",
    "cpu_seconds_per_distinct_held_grasp", "filtered_cpu_seconds_per_held_grasp", "filtered_cpu_seconds_per_distinct_held_grasp",
    "E_post_median_initial", "E_post_median_final", "iterations_to_random_final_E_post", "threshold_reached_fraction", "convergence_ratio",
    "seed_protocol_lift_success_rate", "seed_protocol_lift_success_ci95_low", "seed_protocol_lift_success_ci95_high",
    "fit_rotation_error_deg_median", "fit_translation_error_mm_median", "fit_joint_error_rad_mean",
)  # fmt: skip
# Readable headers of the ladder's own columns (the fit rung's pose errors against the grasps it reconstructs).
LADDER_COLUMN_LABELS = {
    "fit_rotation_error_deg_median": "palm rotation error (°, median)",
    "fit_translation_error_mm_median": "palm position error (mm, median)",
    "fit_joint_error_rad_mean": "joint error (rad, mean)",
}
LENIENT = "seed_protocol_lift_success"  # the same grasps under the DexLite write-up's (Murali) more lenient lift test (evaluate.seed_protocol)
# The methods of the main comparison, in the order the compact table lists them.
HEADLINE_METHODS = ("cvae_post", "random_post", "cvae_raw", "shipped_post", "shipped_raw", "seed", "dexgraspnet")
HEADLINE_METHOD = "cvae_post"  # the pipeline's product: the sentence leads with it when present
RUNG_ORDER = ("fit", "in_distribution", "heldout")
# Within a rung: each kind of start raw, then post-optimized; the random-start baseline last.
LADDER_METHOD_ORDER = ("cvae_recon", "cvae_recon_post", "cvae_prior_train", "cvae_prior_train_post", "cvae_raw", "cvae_post", "random_post")
HISTOGRAMS = (("E_fc", "E_fc"), ("penetration_mm", "penetration (mm)"), ("contact_distance_mm", "contact distance (mm)"))
# Bars of the success chart: (rate column, legend); the per-object rate is a small marker instead.
SUCCESS_BARS = (("lift_success_rate", "lift test"), ("six_dir_success_rate", "six-direction test"))
OBJECT_MARKER_LABEL = "objects with ≥ 1 lifted grasp"
CSV_FILES = ("metrics.csv", "per_object.csv", "convergence.csv", "budget.csv")
# The run's key settings: (label, path in the config). Training steps actually run come from the history.
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
    ("training batch size", ("train", "batch_size")),
    ("CVAE syntheses per held-out object", ("sample", "synthesis_grasps_per_object")),
    ("post-optimization iterations", ("post_optimize", "annealing", "iterations")),
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
    csv_links: Mapping[str, str] = field(default_factory=dict)  # CSV file name -> link relative to the page
    budget: object | None = None  # budget.csv: lift success after each post-optimization budget (optional)
    seed: int = 0  # seeds the random choice of pictured grasps
    learning_curve: object | None = None  # the shipped model's learning curve (docs/learning_curve.csv; optional)
    run_facts: Sequence[tuple[str, str]] = ()  # (label, value): report date, code commit, wall time, machine (report.run_facts)


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


def success_figure(metrics_df):
    """Horizontal bars per method: lift and six-direction success side by side, error bars the object-bootstrap 95% intervals.

    The share of objects with at least one lifted grasp is a small marker on the lift bar,
    not a bar of its own (it is high whenever a method lifts anything, and would dominate).
    A rate that was not measured (NaN, e.g. the six-direction test switched off) gets no
    bar and a "not run" mark, never a bar at 0%. None when no method has a lift rate.
    """
    frame = headline_rows(metrics_df) if metrics_df is not None and len(metrics_df) else metrics_df
    frame = frame.dropna(subset=["lift_success_rate"]) if frame is not None and len(frame) else frame
    if frame is None or not len(frame):
        return None
    plt = _plt()
    from matplotlib.patches import Patch

    several_splits = "split" in frame.columns and frame["split"].nunique() > 1
    labels = [method_label(m) + (f" ({split_label(s)})" if several_splits else "") for m, s in zip(frame["method"], frame.get("split", frame["method"]))]
    y = np.arange(len(frame))[::-1].astype(float)  # first row at the top
    fig, ax = plt.subplots(figsize=(7.5, 0.75 * len(frame) + 1.1))
    height = 0.8 / len(SUCCESS_BARS)
    not_run = []
    for k, (column, name) in enumerate(SUCCESS_BARS):
        values = frame[column].astype(float).to_numpy() * 100 if column in frame.columns else np.full(len(frame), np.nan)
        measured = np.isfinite(values)
        positions = y + (0.5 - k) * height
        interval = column.replace("_rate", "_boot_ci95")
        error = None
        if f"{interval}_low" in frame.columns:
            low = frame[f"{interval}_low"].astype(float).to_numpy() * 100
            high = frame[f"{interval}_high"].astype(float).to_numpy() * 100
            error = np.nan_to_num(np.stack([values - low, high - values])[:, measured], nan=0.0)
        if measured.any():
            ax.barh(positions[measured], values[measured], height, color=f"C{k}", label=name, xerr=error, capsize=2, error_kw={"lw": 0.8})
            ends = values[measured] + (error[1] if error is not None else 0.0)
            for position, value, end in zip(positions[measured], values[measured], ends):
                ax.text(min(end, 88) + 1.5, position, f"{value:.1f}%", va="center", ha="left", fontsize=7)
        else:
            not_run.append(Patch(facecolor="none", edgecolor=f"C{k}", label=f"{name} (not run)"))
        for position in positions[~measured]:
            ax.text(1, position, "not run", fontsize=7, ha="left", va="center", color="grey")
    if "object_success_rate" in frame.columns:
        objects = frame["object_success_rate"].astype(float).to_numpy() * 100
        shown = np.isfinite(objects)
        if shown.any():
            ax.plot(objects[shown], (y + 0.5 * height)[shown], linestyle="none", marker="|", markersize=9, mew=1.5, color="0.25", label=OBJECT_MARKER_LABEL)
    ax.set_yticks(y, labels, fontsize=8)
    ax.set_xlabel("grasps held (%)")
    ax.set_xlim(0, 100)
    ax.set_title("error bars: object-level bootstrap 95% interval (objects resampled)", fontsize=8)
    ax.legend(handles=ax.get_legend_handles_labels()[0] + not_run, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.45 / (0.75 * len(frame) + 1.1) - 0.1), ncol=3, frameon=False)
    fig.tight_layout()
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
                ax.hist(np.clip(v, bins[0], bins[-1]), bins=bins, histtype="step", lw=1.4, label=method_label(method), density=True)
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
        line = ax.plot(group["iteration"], group["median"], label=f"{method_label(method)} (median)")[0]
        ax.fill_between(group["iteration"], group["q25"], group["q75"], color=line.get_color(), alpha=0.2)
    if (frame[["q25", "median", "q75"]].to_numpy() > 0).all():
        ax.set_yscale("log")
    ax.set_xlabel("post-optimization iteration")
    ax.set_ylabel(energy)
    ax.legend(fontsize=7)
    return figure_png_base64(fig)


def budget_plot(budget) -> str | None:
    """Lift success after each post-optimization budget (iterations), per method, with Wilson 95% bands."""
    if budget is None or not len(budget) or not {"method", "iteration", "lift_success_rate"} <= set(budget.columns):
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.5, 3.2))
    for method, group in budget.groupby("method", sort=False):
        group = group.sort_values("iteration")
        rate = group["lift_success_rate"].astype(float) * 100
        line = ax.plot(group["iteration"], rate, marker="o", ms=3, label=method_label(str(method)))[0]
        if {"lift_ci95_low", "lift_ci95_high"} <= set(group.columns):
            ax.fill_between(group["iteration"], group["lift_ci95_low"].astype(float) * 100, group["lift_ci95_high"].astype(float) * 100,
                            color=line.get_color(), alpha=0.15)  # fmt: skip
    ax.set_xlabel("post-optimization iterations")
    ax.set_ylabel("held in lift test (%)")
    ax.set_ylim(0, 100)
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


def pick_examples(simulated: GraspSet, method: str, count: int, seed: int = 0) -> list[tuple[int, bool]]:
    """Up to ``count`` lift successes and ``count`` lift failures of a method (rows, success flag), drawn at random.

    Drawn uniformly without replacement among the method's pictureable grasps of each
    outcome by a generator seeded with ``seed`` and the method's name, so a page shows
    typical grasps, not hand-picked ones, and the same inputs give the same pictures.
    Invalid grasps (no usable pose, not simulated) are not pictured.
    """
    methods = np.asarray([str(m) for m in simulated.arrays["method"]])
    success = np.asarray(simulated.arrays.get("lift_success", np.zeros(len(simulated), bool)), dtype=bool)
    picturable = ~invalid_flags(simulated.arrays)
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, zlib.crc32(method.encode())])
    picks = []
    for outcome in (True, False):
        rows = np.nonzero((methods == method) & (success == outcome) & picturable)[0]
        chosen = rng.choice(rows, size=min(count, len(rows)), replace=False) if len(rows) else rows
        picks += [(int(r), outcome) for r in sorted(chosen)]
    return picks


def outcome_of(arrays: Mapping[str, np.ndarray], row: int) -> tuple[str, str, str]:
    """(headline, detail, css class) of one simulated grasp, from both tests.

    Held: lifted and held against all six pushes; lifted only: it rose with the hand but
    fails a push (often a palm-up carry, the object resting on the palm); dropped: it did
    not rise with the hand.
    """
    lifted = bool(np.asarray(arrays["lift_success"])[row]) if "lift_success" in arrays else False
    detail = []
    pushes = None
    if "six_dir_passed" in arrays:
        passed = np.asarray(arrays["six_dir_passed"])[row]
        pushes = int(np.sum(passed))
        detail.append(f"held against {pushes} of {len(passed)} pushes")
    elif "six_dir_success" in arrays:
        pushes = 6 if bool(np.asarray(arrays["six_dir_success"])[row]) else 0
        detail.append("held against all six pushes" if pushes == 6 else "fails the six-direction test")
    else:
        detail.append("six-direction test not run")
    reason = str(arrays["failure_reason"][row]) if "failure_reason" in arrays else ""
    if not lifted and reason:
        detail.append(reason)
    if lifted and (pushes is None or pushes == 6):
        return "HELD", " · ".join(detail), "held"
    if lifted:
        return "LIFTED, FAILS PUSHES", " · ".join(detail), "partial"
    return "DROPPED", " · ".join(detail), "dropped"


def contact_points(hand, hand_pose: np.ndarray, contact_index: np.ndarray | None, object_mesh) -> np.ndarray:
    """(4, 3) contact points of a grasp in the object frame (metres).

    The evaluation's own contacts when the store carries them (``contact_index``, the four
    candidates nearest the surface, as the energies used), else those four computed here
    against the object's mesh.
    """
    import torch

    with torch.no_grad():
        frames = hand.forward(torch.as_tensor(np.asarray(hand_pose, dtype=np.float64)[None], dtype=hand.dtype, device=hand.device))
        candidates = hand.contact_candidates(frames)[0].double().cpu().numpy()
    index = None if contact_index is None else np.asarray(contact_index, dtype=np.int64).reshape(-1)
    if index is not None and len(index) and (index >= 0).all() and (index < len(candidates)).all():
        return candidates[index]
    import trimesh

    mesh = trimesh.Trimesh(vertices=object_mesh[0], faces=object_mesh[1], process=False)
    _, distance, _ = trimesh.proximity.closest_point(mesh, candidates)
    return candidates[np.argsort(distance)[:4]]


def grasp_picture_png(hand, simulated: GraspSet, row: int, objects_dirs, size_px: int = 260) -> bytes:
    """Two viewpoints of one grasp (the renderer's hand and object) with its four contact points as red dots."""
    from dexlite_pipeline.report.render import DEFAULT_VIEWS_DEG, draw_grasp, grasp_table, hand_mesh_world, object_mesh_world

    plt = _plt()
    pose = np.asarray(simulated.hand_pose[row], dtype=np.float64)
    hand_mesh = hand_mesh_world(hand, pose)
    object_mesh = object_mesh_world(objects_dirs, str(simulated.object_id[row]), float(simulated.scale[row]))
    index = simulated.arrays["contact_index"][row] if "contact_index" in simulated.arrays else None
    contacts = contact_points(hand, pose, index, object_mesh)
    dpi = 100
    fig = plt.figure(figsize=(size_px * len(DEFAULT_VIEWS_DEG) / dpi, size_px / dpi), dpi=dpi)
    for k, (elev, azim) in enumerate(DEFAULT_VIEWS_DEG):
        ax = fig.add_subplot(1, len(DEFAULT_VIEWS_DEG), k + 1, projection="3d")
        draw_grasp(ax, hand_mesh, object_mesh, elev, azim, grasp_table(simulated, row))
        ax.computed_zorder = False  # the dots are drawn over the meshes, so occluded contacts still show
        ax.scatter(contacts[:, 0], contacts[:, 1], contacts[:, 2], s=42, c="#e00000", edgecolors="white", linewidths=0.8, zorder=10, depthshade=False)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=1, wspace=0)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    plt.close(fig)
    return buffer.getvalue()


def gallery_methods(inputs: ReportInputs) -> list[str]:
    """The simulated methods in the order of the tables (headline rows, then the ladder's rungs, then the rest)."""
    present = set(str(m) for m in inputs.simulated.arrays["method"])
    table_order = list(dict.fromkeys(headline_rows(inputs.metrics)["method"])) if inputs.metrics is not None and len(inputs.metrics) else []
    table_order += [m for m in LADDER_METHOD_ORDER if m not in table_order]  # then the ladder's rows, rung by rung
    return [m for m in table_order if m in present] + sorted(present - set(table_order))


def interactive_view_html(inputs: ReportInputs) -> str:
    """The gallery's grasps in the interactive 3-D view (report.grasp_view), embedded with plotly.js (~4.7 MB)."""
    from dexlite_pipeline.report.grasp_view import grasp_view_div

    simulated = inputs.simulated
    if simulated is None or len(simulated) == 0 or inputs.rendered_per_method == 0:
        return "<p>No simulated grasps to show.</p>"
    rows = [row for method in gallery_methods(inputs) for row, _ in pick_examples(simulated, method, inputs.rendered_per_method, inputs.seed)]
    try:
        div = grasp_view_div(simulated, rows, inputs.objects_dirs)
    except (ValueError, OSError) as exc:
        log.warning("report: no interactive view: %s", exc)
        return f"<p>Not available: {html.escape(str(exc))}</p>"
    return div or "<p>No grasp to show.</p>"


def grasp_gallery(inputs: ReportInputs) -> str:
    """HTML of randomly drawn lift successes and failures for each method, outcome in large type."""
    simulated = inputs.simulated
    if simulated is None or len(simulated) == 0 or inputs.rendered_per_method == 0:
        return "<p>No simulated grasps to picture.</p>"
    from dexlite_pipeline.hand import ShadowHand

    hand = ShadowHand()
    parts = []
    for method in gallery_methods(inputs):
        cells = []
        for row, _ in pick_examples(simulated, method, inputs.rendered_per_method, inputs.seed):
            headline, detail, css = outcome_of(simulated.arrays, row)
            object_id, scale = str(simulated.object_id[row]), float(simulated.scale[row])
            facts = [object_id, f"scale {scale:.3f}"]
            for key, name in (("penetration_mm", "penetration"), ("contact_distance_mm", "contact distance")):
                if key in simulated.arrays and np.isfinite(simulated.arrays[key][row]):
                    facts.append(f"{name} {float(simulated.arrays[key][row]):.1f} mm")
            caption = (
                f"<div class='outcome {css}'>{html.escape(headline)}</div>"
                f"<div class='detail'>{html.escape(detail)}</div><div class='facts'>{html.escape(' · '.join(facts))}</div>"
            )
            alt = f"{method_label(method)}: {headline.lower()}, {object_id}"
            try:
                png = grasp_picture_png(hand, simulated, row, inputs.objects_dirs)
            except (ValueError, OSError) as exc:
                log.warning("report: cannot render %s row %d: %s", method, row, exc)
                cells.append(f"<figure><figcaption>{caption}<div class='facts'>not rendered: {html.escape(str(exc))}</div></figcaption></figure>")
                continue
            cells.append(f"<figure>{_img(base64.b64encode(png).decode('ascii'), alt)}<figcaption>{caption}</figcaption></figure>")
        parts.append(f"<h3>{html.escape(method_label(method))} <span class='id'>({html.escape(method)})</span></h3><div class='gallery'>{''.join(cells) or '<p>none</p>'}</div>")
    return "".join(parts)


def _format(value) -> str:
    if isinstance(value, (float, np.floating)):
        if np.isinf(value):
            return "∞" if value > 0 else "−∞"
        if not np.isfinite(value):
            return "—"
        return f"{value:.3g}" if abs(value) < 1e4 else f"{value:.0f}"
    return html.escape(str(value))


def _number(value, digits: int = 1) -> str:
    try:
        value = float(value)
    except (TypeError, ValueError):
        return "—"
    return f"{value:.{digits}f}" if math.isfinite(value) else "—"


def _interval_columns(row, name: str) -> tuple[object, object]:
    """The object-bootstrap interval of a rate when present, else the Wilson one."""
    for kind in ("_boot_ci95", "_ci95"):
        low, high = row.get(f"{name}{kind}_low"), row.get(f"{name}{kind}_high")
        if interval_text(low, high):
            return low, high
    return None, None


def _rate_cell(row, name: str, css: str = "") -> str:
    """A rate as "17.5%" in bold with its 95% interval in small type."""
    value = row.get(f"{name}_rate")
    text = percent_text(value)
    if text == "not run":
        return f"<td class='rate na {css}'>not run</td>"
    interval = interval_text(*_interval_columns(row, name))
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
    """Whether the rows carry the lift rate under the write-up's lenient test (evaluate.seed_protocol)."""
    column = f"{LENIENT}_rate"
    return frame is not None and column in frame.columns and np.isfinite(frame[column].astype(float)).any()


LENIENT_HEADER = "<th class='lenient'>lift, the write-up's test</th>"


def _diversity_cells(row, prefix: str = "") -> list[str]:
    """Distinct held grasps per object and the surface coverage (``prefix`` "filtered_": after the energy filter)."""
    coverage = percent_text(row.get(f"{prefix}surface_coverage_mean"))
    return [f"<td class='diversity'>{_number(row.get(f'{prefix}distinct_held_per_object_mean'))}</td>",
            f"<td class='diversity'>{coverage if coverage != 'not run' else '—'}</td>"]  # fmt: skip


def _cost_text(seconds) -> str:
    """Seconds for a cost cell; "∞" when attempts cost time and gave nothing."""
    try:
        value = float(seconds)
    except (TypeError, ValueError):
        return "—"
    return "∞" if value == math.inf else seconds_text(value)


def _cpu_seconds_cell(row) -> str:
    """CPU-seconds per distinct held grasp, per attempt and after the filter ("5.2 s / 7.1 s")."""
    per_attempt, filtered = (row.get(f"{p}cpu_seconds_per_distinct_held_grasp") for p in ("", "filtered_"))
    return f"<td>{_cost_text(per_attempt)} / {_cost_text(filtered)}</td>"


def _filtered_rate_cell(row) -> str:
    """The lift rate after the energy filter; "none pass" when no attempt passed, "—" when the filter was not measured."""
    if not _filter_measured(row):
        return "<td class='rate na'>—</td>"
    if _finite(row.get("filtered_n_grasps")) and int(row["filtered_n_grasps"]) == 0:
        return "<td class='rate na'>none pass</td>"
    return _rate_cell(row, "filtered_lift_success")


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


def compact_table_html(frame) -> str:
    """The headline table: readable names, grasps, lift and six-direction rates with intervals, the lift rate beside its
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
        cells += [_grasps_cell(row), _rate_cell(row, "lift_success"), *_diversity_cells(row), _rate_cell(row, "six_dir_success")]
        if lenient:
            cells.append(_rate_cell(row, LENIENT, "lenient"))
        cells += [_pass_cell(row), _filtered_rate_cell(row), *_diversity_cells(row, "filtered_"), _cpu_seconds_cell(row)]
        cells += [
            f"<td>{_number(row.get('penetration_mean_mm'))}</td>", f"<td>{_number(row.get('contact_distance_mean_mm'))}</td>",
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
                  _grasps_cell(row), _rate_cell(row, "lift_success"), *_diversity_cells(row), _rate_cell(row, "six_dir_success")]  # fmt: skip
        if lenient:
            cells.append(_rate_cell(row, LENIENT, "lenient"))
        cells += [_pass_cell(row), _filtered_rate_cell(row), *_diversity_cells(row, "filtered_")]
        cells += [f"<td>{_format(row[c])}</td>" for c in extra]
        body.append("<tr>" + "".join(cells) + "</tr>")
    return (
        "<h2>Learning ladder</h2><p class='note'>Whether the model learned, rung by rung: its own training grasps encoded and "
        "decoded (the originals all held), samples on the objects it was trained on, and samples on objects it never saw. "
        "A rung it fails explains the rungs above it.</p>"
        f"<table class='compact'><thead>{head}</thead><tbody>{''.join(body)}</tbody></table>"
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
    if _finite(row.get("filtered_n_grasps")) and int(row["filtered_n_grasps"]) == 0:
        return "none passing"
    return percent_text(row.get("filtered_lift_success_rate"))


def _finite(value) -> bool:
    try:
        return value is not None and math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


def _filter_measured(row) -> bool:
    """Whether a metrics row carries the equal energy filter (its pass fraction)."""
    return _finite(row.get("energy_threshold_pass_rate"))


def _diversity_text(row, prefix: str) -> str:
    """" (2.5 distinct held grasps per object, 31.0% of the surface touched)"; empty when not measured."""
    if not _finite(row.get(f"{prefix}distinct_held_per_object_mean")):
        return ""
    coverage = row.get(f"{prefix}surface_coverage_mean")
    touched = f", {percent_text(coverage)} of the surface touched" if _finite(coverage) else ""
    return f" ({_number(row[f'{prefix}distinct_held_per_object_mean'])} distinct held grasps per object{touched})"


def _filter_text(row) -> str:
    """The lead row after the equal energy filter; empty when the filter was not measured."""
    if not _filter_measured(row):
        return ""
    if _finite(row.get("filtered_n_grasps")) and int(row["filtered_n_grasps"]) == 0:
        return "; none of its attempts pass the energy filter every method goes through"
    return (f"; after the energy filter every method goes through ({percent_text(row['energy_threshold_pass_rate'])} of attempts pass), "
            f"{_filtered_rate_text(row)} held in the lift test{_diversity_text(row, 'filtered_')}")  # fmt: skip


def full_table_html(metrics_df) -> str:
    """Every column of metrics.csv a reader may want, raw fractions, folded."""
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
    rows = "".join(f"<tr><td>{html.escape(str(k))}</td><td>{_format(v)}</td></tr>" for k, v in sorted(lift_config.items()))
    return f"<table><thead><tr><th>constant</th><th>value</th></tr></thead><tbody>{rows}</tbody></table>"


STYLE = """
body{font-family:system-ui,sans-serif;margin:1.2em 2em;max-width:1400px;color:#222}
h1{font-size:22px;margin:0 0 .4em}h2{font-size:18px;margin:1.4em 0 .4em}h3{font-size:15px}
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
        return _format(float(value) * scale) if isinstance(value, (int, float)) else "?"

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
        "compact table and the error bars show.</p>"
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
    """The shipped model's learning curve (its large run): plot and table."""
    from dexlite_pipeline.report.learning_curve import curve_figure

    columns = ["point", "seed", "training_objects", "training_grasps", "method", "n_grasps", "lift_success_rate", "lift_success_ci95_low",
               "lift_success_ci95_high", "six_dir_success_rate", "seconds_per_grasp"]  # fmt: skip
    table = curve[[c for c in columns if c in curve.columns]].to_html(index=False, float_format=lambda v: f"{v:.3g}", na_rep="—")
    return (
        "<h2>Learning curve of the shipped model's run</h2><p class='note'>Held-out success on the benchmark split against the number of "
        "training objects (nested subsets of the large run's objects, same sampling and post-optimization budget; Wilson 95%). From "
        "docs/learning_curve.csv of this checkout: it describes the shipped model's training, not this run's.</p>"
        + _img(figure_png_base64(curve_figure(curve)), "learning curve") + f"<details><summary>table</summary>{table}</details>"
    )


def build_report_html(inputs: ReportInputs) -> str:
    """The whole page as a string."""
    headline = headline_rows(inputs.metrics)
    sections = [f"<h1>{html.escape(inputs.title)}</h1>", run_facts_html(inputs.run_facts)]
    sections.append(f"<p class='result'>{html.escape(headline_sentence(headline, inputs.lift_config))}</p>")
    sections.append(compact_table_html(headline))
    sections.append(
        "<p class='note'>Both tests count with equal weight: “lift test” = the object rose with the hand; "
        "“six pushes” = it stayed put under a push of about its own weight along each of ±x, ±y, ±z in turn. "
        "Small numbers: object-level bootstrap 95% interval (objects resampled)"
        + ("; “lift, the write-up's test”: the same grasps under the more lenient lift test of the DexLite write-up (Murali) (Wilson interval), for comparison "
           "with its published numbers" if has_lenient(headline) else "")
        + ". Definitions and every column: end of the page.</p>"
    )
    sections.append(ladder_html(inputs.metrics))
    for title, image in (
        ("Success per method", success_plot(inputs.metrics)),
        ("Energies and penetration", histogram_plot(inputs.simulated)),
        ("Post-optimization convergence (median, interquartile band)", convergence_plot(inputs.convergence)),
        ("Lift success against the post-optimization budget (Wilson 95% band)", budget_plot(inputs.budget)),
        ("CVAE training curves", training_plot(inputs.history)),
    ):
        if image is None and title.startswith("Lift success against"):
            continue  # only runs that lift-test post-optimization budgets have this plot
        sections.append(f"<h2>{html.escape(title)}</h2>" + (_img(image, title) if image else "<p>Not available in this run.</p>"))
        if title.startswith("Post-optimization convergence"):
            sections.append(convergence_note(inputs.metrics, inputs.convergence))
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
    if inputs.per_object is not None and len(inputs.per_object):
        per_object = inputs.per_object.to_html(index=False, float_format=lambda v: f"{v:.3g}", na_rep="—")
        sections.append(f"<h2>Per object</h2><details><summary>{len(inputs.per_object)} rows</summary>{per_object}</details>")
    sections.append("<h2>Run settings</h2>" + run_settings_html(inputs.config, inputs.objects_dirs, inputs.history))
    sections.append("<h2>Physical constants of the lift and six-direction tests</h2>" + constants_table_html(inputs.lift_config))
    sections.append(
        "<h2>All numbers</h2>" + csv_links_html(inputs.csv_links) + definitions_html(inputs.lift_config)
        + "<details><summary>metrics.csv, every method and column</summary>" + full_table_html(inputs.metrics) + "</details>"
    )  # fmt: skip
    return f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(inputs.title)}</title><style>{STYLE}</style></head><body>{''.join(sections)}</body></html>"


@dataclass(frozen=True)
class EvaluationFiles:
    """The evaluation's outputs the report reads (budget and record may be absent or empty)."""

    metrics: str
    per_object: str
    convergence: str
    budget: str | None = None
    record: str | None = None

    def tables(self) -> dict[str, str]:
        """Link name (the file name) -> path of each table that exists."""
        paths = (self.metrics, self.per_object, self.convergence, self.budget)
        return {Path(p).name: p for p in paths if p and Path(p).is_file()}


def load_report_inputs(files: EvaluationFiles, sim_paths: list[str], history_path: str | None, objects_dirs: list[str],
                       config: dict, page_path: str, learning_curve_path: str | None = None, benchmarks_dir: str | None = None) -> ReportInputs:
    """Everything the page shows, read from the evaluation's files; CSV links relative to the page's folder.

    ``benchmarks_dir``: the run's job benchmark files (logs/benchmarks), for the wall time at the top.
    """
    import json
    import os

    import pandas as pd

    from dexlite_pipeline.evaluation.protocol import concatenate_shards, evaluate_config_from
    from dexlite_pipeline.evaluation.step_keys import REPORT_KEYS
    from dexlite_pipeline.io.grasp_store import read_grasp_store
    from dexlite_pipeline.report.run_facts import run_facts
    from dexlite_pipeline.settings import build_config

    for path in (files.metrics, files.per_object, files.convergence):
        if not Path(path).is_file():
            raise FileNotFoundError(f"{path}: evaluation output missing (run dexlite evaluate --step aggregate)")
    record = json.loads(Path(files.record).read_text()) if files.record and Path(files.record).is_file() else {}
    budget = pd.read_csv(files.budget) if files.budget and Path(files.budget).is_file() and Path(files.budget).stat().st_size else None
    history = pd.read_csv(history_path) if history_path and Path(history_path).is_file() else None
    page_dir = Path(page_path).parent
    return ReportInputs(
        metrics=pd.read_csv(files.metrics),
        per_object=pd.read_csv(files.per_object),
        convergence=pd.read_csv(files.convergence),
        history=history,
        simulated=concatenate_shards([read_grasp_store(p) for p in sim_paths]),
        lift_config=record.get("lift_config") or {},
        objects_dirs=objects_dirs,
        rendered_per_method=evaluate_config_from(config, REPORT_KEYS).rendered_per_method,
        config=config,
        csv_links={name: Path(os.path.relpath(path, page_dir)).as_posix() for name, path in files.tables().items()},
        seed=build_config(config).seed,
        budget=budget,
        learning_curve=pd.read_csv(learning_curve_path) if learning_curve_path else None,
        run_facts=run_facts(config, benchmarks_dir),
    )
