"""Held-out rows per named object set (evaluation.subsets): counts rebuilt from per-object rates, costs from metrics.csv."""

import math

import pandas as pd
import pytest

from dexlite_pipeline.evaluation.subsets import family_subsets, split_subsets, subset_rows


def test_subset_rows_count_each_set_apart():
    per_object = pd.DataFrame({
        "method": ["cvae_post"] * 3 + ["optimization"] * 3, "split": ["heldout"] * 5 + ["train"],
        "object_id": ["a", "b", "c", "a", "b", "c"], "n_grasps": [16, 16, 8, 16, 16, 16],
        "lift_success_rate": [0.5, 0.25, 1.0, 0.0, 0.125, 1.0], "six_dir_success_rate": [0.25, 0.25, 0.5, 0.0, float("nan"), 1.0],
        "n_distinct_held": [4, 2, 3, 0, 2, 9],
    })  # fmt: skip
    metrics = pd.DataFrame({"method": ["cvae_post", "optimization"], "split": ["heldout", "heldout"], "seconds_per_grasp": [0.1, 1.0]})
    rows = subset_rows(metrics, per_object, {"ab": ["a", "b"], "c": ["c"], "none": ["z"]}, ["cvae_post", "optimization", "random_post"])
    post_ab = rows[(rows.method == "cvae_post") & (rows.subset == "ab")].iloc[0]
    assert (post_ab.objects, post_ab.attempts, post_ab.held) == (2, 32, 12)
    assert post_ab.held_rate == pytest.approx(12 / 32) and post_ab.held_ci95_low < 12 / 32 < post_ab.held_ci95_high
    assert post_ab.six_dir_rate == pytest.approx(8 / 32) and post_ab.distinct_held_per_object == 3.0
    assert post_ab.objects_with_min_distinct == 0.5  # a has 4 distinct held grasps, b 2
    assert post_ab.cpu_seconds_per_distinct_held == pytest.approx(0.1 * 32 / 6)
    # optimization on c is a training-split row: not held out; on a it held nothing (no cost per distinct grasp there)
    assert set(rows[rows.method == "optimization"].subset) == {"ab"}
    assert "none" not in set(rows.subset) and "random_post" not in set(rows.method)
    only_a = subset_rows(metrics, per_object, {"a": ["a"]}, ["optimization"]).iloc[0]
    assert only_a.held == 0 and math.isnan(only_a.cpu_seconds_per_distinct_held)


def test_split_subsets_name_the_prepared_objects_of_each_split():
    from dexlite_pipeline.objects.sources import benchmark_object_list, household_benchmark_list

    household, benchmark = household_benchmark_list()[:2], benchmark_object_list()[:1]
    catalog = pd.DataFrame({"object_id": [*household, *benchmark, "household-mug-000"], "status": ["ok", "failed", "ok", "ok"]})
    assert split_subsets(catalog) == {"household split": household[:1], "benchmark split": benchmark}
    assert split_subsets(catalog[catalog.object_id == "household-mug-000"]) == {}


def test_family_subsets_group_instances_and_perturbations_by_family():
    ids = ["household-mug-003", "pb-random-120", "household-mug-040-p1", "household-bowl-900", "my_scan", "pb-duck"]
    assert family_subsets(ids) == {"bowl": ["household-bowl-900"], "mug": ["household-mug-003", "household-mug-040-p1"],
                                   "other": ["my_scan", "pb-duck"], "procedural": ["pb-random-120"]}
