"""The report's success bars: what is drawn for unmeasured rates, and which interval the error bars show."""

import numpy as np
import pandas as pd

from dexlite_pipeline.report.html import success_figure


def _metrics(six_dir_rate: float) -> pd.DataFrame:
    return pd.DataFrame({
        "method": ["cvae_raw", "cvae_post"], "split": ["heldout", "heldout"],
        "lift_success_rate": [0.2, 0.4], "object_success_rate": [0.4, 0.8], "six_dir_success_rate": [six_dir_rate, six_dir_rate],
        "lift_success_ci95_low": [0.15, 0.35], "lift_success_ci95_high": [0.25, 0.45],  # Wilson: narrow
        "lift_success_boot_ci95_low": [0.0, 0.1], "lift_success_boot_ci95_high": [0.6, 0.9],  # objects resampled: wide
        "six_dir_success_ci95_low": [np.nan, np.nan], "six_dir_success_ci95_high": [np.nan, np.nan],
        "six_dir_success_boot_ci95_low": [np.nan, np.nan], "six_dir_success_boot_ci95_high": [np.nan, np.nan],
    })  # fmt: skip


def _bar_containers(fig):
    from matplotlib.container import BarContainer

    return {c.get_label(): c for c in fig.axes[0].containers if isinstance(c, BarContainer)}


def _bars(fig) -> dict[str, list[float]]:
    return {label: [patch.get_height() for patch in container.patches] for label, container in _bar_containers(fig).items()}


def test_six_direction_rate_not_measured_gets_no_bar_but_a_not_run_mark():
    fig = success_figure(_metrics(np.nan))
    bars = _bars(fig)
    assert "six directions" not in bars and bars["lift (per grasp)"] == [20.0, 40.0]
    assert [t.get_text() for t in fig.axes[0].texts].count("not run") == 2
    assert "six directions (not run)" in [t.get_text() for t in fig.axes[0].get_legend().get_texts()]


def test_measured_zero_is_still_a_bar():
    assert _bars(success_figure(_metrics(0.0)))["six directions"] == [0.0, 0.0]


def test_error_bars_are_the_object_bootstrap_interval():
    fig = success_figure(_metrics(np.nan))
    lift = _bar_containers(fig)["lift (per grasp)"]
    segments = lift.errorbar.lines[2][0].get_segments()
    assert [(float(s[0][1]), float(s[1][1])) for s in segments] == [(0.0, 60.0), (10.0, 90.0)]
    assert "bootstrap" in fig.axes[0].get_title()
