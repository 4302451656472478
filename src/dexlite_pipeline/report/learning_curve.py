"""The learning curve's table and plot: held-out success against the number of training objects.

Rows come from ``benchmarks/experiments/learning_curve.py`` (one per point and method: ``point``, ``seed``,
``training_objects``, ``training_grasps``, optionally ``training_steps``, ``method``, ``n_grasps``,
the lift and six-direction rates with Wilson 95% bounds, ``seconds_per_grasp``); the report shows
the checked-in curve (``docs/learning_curve.csv``) of the shipped model's run. The curve proper is
the points at the run's step budget (the most common one); points trained for another number of
steps are drawn apart, unjoined, so a longer budget is not read as more data.
"""

from __future__ import annotations

CURVE_METHODS = ("cvae_raw", "cvae_post")
# Methods that do not depend on the model (read from the run, drawn as bands): label, colour.
BASELINES = {"random_post": ("random init + post", "grey"), "optimization": ("optimization from scratch", "tab:green")}


def _steps(table):
    """Training steps per row (0 where unknown: baselines, or a table written before the column existed)."""
    import pandas as pd

    return table["training_steps"].fillna(0).astype(int) if "training_steps" in table else pd.Series(0, index=table.index)


def curve_budget(table) -> int:
    """The curve's step budget: the most common training-step count among the model rows (0 when unrecorded)."""
    steps = _steps(table)[table.method.isin(CURVE_METHODS)]
    return int(steps.mode().iloc[0]) if len(steps) else 0


def curve_markdown(table) -> str:
    """The curve as a Markdown table (one row per point and method)."""
    lines = ["| point | seed | training objects / grasps | steps | method | lift (Wilson 95%) | six-direction (95%) | s/grasp |",
             "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for r, steps in zip(table.itertuples(), _steps(table)):
        lines.append(
            f"| {r.point} | {r.seed} | {r.training_objects} / {r.training_grasps} | {steps or '–'} | {r.method} | "
            f"{100 * r.lift_success_rate:.1f}% ({100 * r.lift_success_ci95_low:.1f}–{100 * r.lift_success_ci95_high:.1f}) | "
            f"{100 * r.six_dir_success_rate:.1f}% ({100 * r.six_dir_success_ci95_low:.1f}–{100 * r.six_dir_success_ci95_high:.1f}) | "
            f"{r.seconds_per_grasp:.3f} |"
        )
    return "\n".join(lines)


def curve_figure(table):
    """Held-out lift and six-direction success against training objects (log axis), Wilson 95% bars; random init as a band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    budget, steps = curve_budget(table), _steps(table)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.8), sharey=True)
    for ax, prefix, title in ((axes[0], "lift_success", "lift test"), (axes[1], "six_dir_success", "six-direction test")):
        for method, colour in (("cvae_raw", "tab:blue"), ("cvae_post", "tab:orange")):
            for at_budget in (True, False):
                rows = table[(table.method == method) & ((steps == budget) == at_budget)].sort_values("training_objects")
                if not len(rows):
                    continue
                rate = 100 * rows[f"{prefix}_rate"]
                error = [rate - 100 * rows[f"{prefix}_ci95_low"], 100 * rows[f"{prefix}_ci95_high"] - rate]
                label = method.replace("_", " ") + ("" if at_budget else ", other step budget")
                ax.errorbar(rows.training_objects, rate, yerr=error, marker="o" if at_budget else "s", capsize=3, color=colour, label=label,
                            linestyle="none", markerfacecolor=colour if at_budget else "none")  # fmt: skip
                if at_budget:
                    means = rows.groupby("training_objects")[f"{prefix}_rate"].mean() * 100
                    ax.plot(means.index, means.values, color=colour, alpha=0.6)
        for method, (label, colour) in BASELINES.items():
            baseline = table[table.method == method]
            if len(baseline):
                level = 100 * float(baseline[f"{prefix}_rate"].iloc[0])
                low, high = 100 * float(baseline[f"{prefix}_ci95_low"].iloc[0]), 100 * float(baseline[f"{prefix}_ci95_high"].iloc[0])
                ax.axhline(level, color=colour, linestyle="--", label=label)
                ax.axhspan(low, high, color=colour, alpha=0.12)
        ax.set_xscale("log")
        counts = sorted({int(c) for c in table.training_objects if c > 0})
        ax.set_xticks(counts, [str(c) for c in counts])
        ax.minorticks_off()
        ax.set_xlabel("training objects")
        ax.set_title(f"held-out objects: {title}")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("success rate (%), Wilson 95%")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=3, frameon=False)  # below the plots, clear of the points
    fig.tight_layout(rect=(0, 0.16, 1, 1))
    return fig


def save_curve_figure(table, path) -> None:
    import matplotlib.pyplot as plt

    fig = curve_figure(table)
    fig.savefig(path, dpi=110)
    plt.close(fig)
