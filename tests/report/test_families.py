"""The report's table by family: held-out rows grouped by family, methods in the main comparison's order."""

import pandas as pd
import pytest

from dexlite_pipeline.report.families import family_rows, family_table_html


def _per_object() -> pd.DataFrame:
    rows = [  # method, split, object, attempts, held rate, six-direction rate, distinct held
        ("optimization", "heldout", "household-mug-900", 16, 0.5, 0.25, 8),
        ("optimization", "heldout", "household-mug-901-p1", 16, 0.25, 0.25, 3),
        ("optimization", "heldout", "pb-random-120", 16, 0.0, 0.0, 0),
        ("cvae_post", "heldout", "household-mug-900", 16, 1.0, 1.0, 16),
        ("cvae_post", "heldout", "household-mug-901-p1", 16, 0.75, 0.5, 12),
        ("cvae_post", "heldout", "pb-random-120", 16, 0.125, 0.0, 2),
        ("cvae_post", "train", "household-cup-000", 8, 1.0, 1.0, 8),
    ]
    return pd.DataFrame(rows, columns=["method", "split", "object_id", "n_grasps", "lift_success_rate", "six_dir_success_rate", "n_distinct_held"])


def test_families_group_held_out_objects_and_count_each_apart():
    metrics = pd.DataFrame({"method": ["cvae_post", "optimization"], "split": ["heldout"] * 2, "seconds_per_grasp": [0.1, 1.0]})
    rows = family_rows(metrics, _per_object())
    assert list(zip(rows.subset, rows.method)) == [("mug", "cvae_post"), ("mug", "optimization"),
                                                   ("procedural", "cvae_post"), ("procedural", "optimization")]
    mug_opt = rows[(rows.subset == "mug") & (rows.method == "optimization")].iloc[0]
    assert (mug_opt.objects, mug_opt.attempts, mug_opt.held) == (2, 32, 12)
    assert mug_opt.held_rate == pytest.approx(12 / 32) and mug_opt.distinct_held_per_object == 5.5
    assert mug_opt.objects_with_min_distinct == 0.5  # 8 and 3 distinct held grasps: one of two objects has 4 or more
    text = family_table_html(metrics, _per_object())
    assert text.count("<tr>") == 5 and "procedural" in text and "household-cup" not in text  # the training object stays out


def test_no_held_out_object_no_table():
    per_object = _per_object()
    assert family_table_html(pd.DataFrame({"method": [], "split": [], "seconds_per_grasp": []}), per_object[per_object.split == "train"]) == ""
