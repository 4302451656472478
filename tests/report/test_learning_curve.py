"""The learning curve's table and plot keep points trained for another step budget apart."""

import pandas as pd

from dexlite_pipeline.report.learning_curve import curve_budget, curve_figure, curve_markdown


def _rows(point, objects, steps, gain=0.0):
    return [{"point": point, "seed": 0, "training_objects": objects, "training_grasps": 3 * objects, "training_steps": steps, "method": method,
             "n_grasps": 768, "lift_success_rate": rate, "lift_success_ci95_low": rate - 0.03, "lift_success_ci95_high": rate + 0.03,
             "six_dir_success_rate": rate / 2, "six_dir_success_ci95_low": rate / 2 - 0.02, "six_dir_success_ci95_high": rate / 2 + 0.02,
             "seconds_per_grasp": 0.1} for method, rate in (("cvae_raw", 0.15 + gain), ("cvae_post", 0.4 + gain))]  # fmt: skip


def test_a_longer_budget_is_drawn_and_listed_apart_from_the_curve():
    table = pd.DataFrame(_rows("n10_seed0", 10, 8000) + _rows("all", 566, 8000) + _rows("nall_seed0_steps16000", 566, 16000, gain=0.2))
    assert curve_budget(table) == 8000
    markdown = curve_markdown(table)
    assert "| nall_seed0_steps16000 | 0 | 566 / 1698 | 16000 | cvae_post | 60.0%" in markdown and "| all | 0 | 566 / 1698 | 8000 |" in markdown
    labels = [t.get_text() for t in curve_figure(table).legends[0].get_texts()]
    assert "cvae post" in labels and "cvae post, other step budget" in labels
    # the joined line runs through the budget's points only: its 566-object end is the 8000-step rate
    line = [ln for ln in curve_figure(table).axes[0].get_lines() if len(ln.get_xdata()) == 2 and ln.get_color() == "tab:orange"][0]
    assert list(line.get_xdata()) == [10, 566] and list(line.get_ydata()) == [40.0, 40.0]


def test_a_table_without_step_counts_still_draws():
    table = pd.DataFrame(_rows("n10_seed0", 10, 0) + _rows("all", 566, 0)).drop(columns="training_steps")
    assert curve_budget(table) == 0 and "| all | 0 | 566 / 1698 | – | cvae_raw |" in curve_markdown(table)
    assert len(curve_figure(table).legends) == 1
