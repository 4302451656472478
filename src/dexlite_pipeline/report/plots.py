"""The report's plots, drawn with matplotlib (Agg) and embedded as base64 PNG: success per method (full
size, and narrow for the first screen), energy histograms, post-optimization convergence and budget, CVAE training curves. Each returns
None when its input is absent, so the page can say "not available".
"""

from __future__ import annotations

import base64
import html
import io
import math
import textwrap

import numpy as np

from dexlite_pipeline.evaluation.labels import method_label, split_label
from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.report.tables import headline_rows


HISTOGRAMS = (("E_fc", "E_fc"), ("penetration_mm", "penetration (mm)"), ("contact_distance_mm", "contact distance (mm)"))
# Bars of the success chart: (rate column, legend); the per-object rate is a small marker instead.
SUCCESS_BARS = (("lift_success_rate", "lift test"), ("six_dir_success_rate", "six-direction test"))
OBJECT_MARKER_LABEL = "objects with ≥ 1 lifted grasp"


def figure_png_base64(fig) -> str:
    """A matplotlib figure as base64 PNG (100 dpi, tight box); the figure is closed."""
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def img_tag(data_b64: str, alt: str) -> str:
    """An <img> embedding base64 PNG data, so the page needs no files beside it."""
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data_b64}">'


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def success_figure(metrics_df):
    """The success chart of the main comparison's rows (every split), at the page's full size; None without a lift rate."""
    frame = headline_rows(metrics_df) if metrics_df is not None and len(metrics_df) else metrics_df
    return rates_figure(frame, label_chars=40)


def rates_figure(frame, width_in: float = 7.5, row_in: float = 0.75, label_chars: int | None = None):
    """Horizontal bars per row of ``frame``: lift and six-direction success side by side, error bars the object-bootstrap 95% intervals.

    The share of objects with at least one lifted grasp is a small marker on the lift bar,
    not a bar of its own (it is high whenever a method lifts anything, and would dominate).
    A rate that was not measured (NaN, e.g. the six-direction test switched off) gets no
    bar and a "not run" mark, never a bar at 0%. None when no row has a lift rate.
    ``width_in`` and ``row_in`` (inches per row) size the figure; ``label_chars`` wraps the
    method names at that many characters, so a narrow chart keeps its bars wide.
    """
    frame = frame.dropna(subset=["lift_success_rate"]) if frame is not None and len(frame) else frame
    if frame is None or not len(frame):
        return None
    plt = pyplot()
    from matplotlib.patches import Patch
    from matplotlib.transforms import offset_copy

    several_splits = "split" in frame.columns and frame["split"].nunique() > 1
    labels = [method_label(m) + (f" ({split_label(s)})" if several_splits else "") for m, s in zip(frame["method"], frame.get("split", frame["method"]))]
    if label_chars:
        labels = [textwrap.fill(label, label_chars) for label in labels]
    y = np.arange(len(frame))[::-1].astype(float)  # first row at the top
    height_in = row_in * len(frame) + 1.1
    fig, ax = plt.subplots(figsize=(width_in, height_in))
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
    ax.set_xlabel("grasps held per attempt (%)")
    ax.set_xlim(0, 100)
    ax.set_title("error bars: object-level bootstrap 95% interval (objects resampled)", fontsize=8)
    fig.tight_layout()
    # the legend under the axis label, a fixed distance below the axes whatever the figure's height (the saved box takes it in)
    below = offset_copy(ax.transAxes, fig=fig, y=-0.45, units="inches")
    ax.legend(handles=ax.get_legend_handles_labels()[0] + not_run, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, 0.0), bbox_transform=below,
              ncol=3, frameon=False)  # fmt: skip
    return fig


def success_plot(metrics_df) -> str | None:
    """The success bars as base64 PNG (None when there is nothing to show)."""
    fig = success_figure(metrics_df)
    return figure_png_base64(fig) if fig is not None else None


# The first screen's chart: narrow (it sits beside the summary table), a row per method, names wrapped.
FIRST_SCREEN_CHART = {"width_in": 5.0, "row_in": 0.5, "label_chars": 24}


def held_per_attempt_plot(rows) -> str | None:
    """The first screen's chart of ``rows`` (one split's methods) as base64 PNG, sized to fit beside the summary table; None when empty."""
    fig = rates_figure(rows, **FIRST_SCREEN_CHART)
    return figure_png_base64(fig) if fig is not None else None


def histogram_plot(simulated: GraspSet | None) -> str | None:
    """Per-method histograms of E_fc, penetration and contact distance."""
    if simulated is None or len(simulated) == 0 or "method" not in simulated.arrays:
        return None
    present = [(k, label) for k, label in HISTOGRAMS if k in simulated.arrays]
    if not present:
        return None
    plt = pyplot()
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
    plt = pyplot()
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
    plt = pyplot()
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
    plt = pyplot()
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
