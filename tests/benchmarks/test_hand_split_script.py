"""benchmarks/experiments/hand_split.py: a row of counts from a tested grasp set, the failures by reason, seeds pooled."""

import numpy as np

from dexlite_pipeline.io.grasp_store import GraspSet


def _tested():
    # five attempts on two objects: two held (one also in six directions), a hopeless one, a dropped one, a deep start
    return GraspSet({
        "hand_pose": np.zeros((5, 22), np.float32), "object_id": np.asarray(["a", "a", "b", "b", "b"], dtype=object),
        "scale": np.ones(5, np.float32), "lift_success": np.asarray([1, 1, 0, 0, 0], bool),
        "six_dir_success": np.asarray([1, 0, 0, 0, 0], bool), "initial_penetration_mm": np.asarray([1.0, 1.4, 0.5, 2.5, 0.2]),
        "passes_energy_thresholds": np.asarray([1, 1, 0, 0, 0], bool),
        "failure_reason": np.asarray(["", "", "not_tested: optimization stopped early (hopeless)", "initial_penetration: 2.5 mm", ""],
                                     dtype=object),
    })  # fmt: skip


def test_row_counts_and_failure_reasons(benchmark_script):
    script = benchmark_script("hand_split")
    row = script.row_of(_tested(), np.asarray([0, 0, -1, -1, -1]), 2, 12.0, hand="leap", seed=1, label="x")
    assert (row["attempts"], row["held"], row["six"], row["distinct"], row["passes"]) == (5, 2, 1, 1, 2)
    assert row["depth_held_mm"] == [1.0, 1.4] and row["failures"] == {"hopeless": 1, "initial_penetration": 1, "dropped": 1}
    line = script.table_line(row)
    assert line.startswith("| leap | 1 | x | 2/5 = 40.0% [") and "| 1 = 20.0% [" in line and "| 0.50 | 1.20 | 2 |" in line


def test_seeds_pool_into_one_row_per_hand_and_label(benchmark_script):
    script = benchmark_script("hand_split")
    row = script.row_of(_tested(), np.asarray([0, 1, -1, -1, -1]), 2, 10.0, hand="leap", seed=0, label="x")
    lines = script.tabulate([row, {**row, "seed": 1}, {**row, "hand": "allegro"}])
    assert len(lines) == 4 and lines[2].startswith("| leap | pooled (2) | x | 4/10 = 40.0% [") and lines[2].endswith("| 20 |")
    assert "hopeless 2, initial_penetration 2, dropped 2" in lines[2] and lines[3].startswith("| allegro | 0 |")
