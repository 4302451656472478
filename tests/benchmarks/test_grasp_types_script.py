"""benchmarks/experiments/grasp_types.py: per-object counts from a dexlite grasp output folder and the family table."""

import numpy as np
import pytest

from dexlite_pipeline.io.grasp_store import GraspSet, write_grasp_store


def _store(path, grasp_type="pinch"):
    # bowl: 4 pinch attempts, 3 held (two near-duplicates), one of them also against the six pushes; hammer: 2, none held
    objects = ["user-household-bowl-900"] * 4 + ["user-household-hammer-900"] * 2
    grasps = GraspSet({
        "hand_pose": np.zeros((6, 28), np.float32), "object_id": np.asarray(objects, dtype=object), "scale": np.ones(6, np.float32),
        "lift_success": np.asarray([1, 1, 1, 0, 0, 0], bool), "six_dir_success": np.asarray([1, 0, 0, 0, 0, 0], bool),
        "distinct_label": np.asarray([0, 1, 1, -1, -1, -1], np.int64), "initial_penetration_mm": np.asarray([1.0, 1.2, 1.4, 3.0, 0.5, 0.1]),
        "failure_reason": np.asarray(["", "", "", "initial_penetration: 3.0 mm", "dropped: ratio 0.1", "dropped: ratio 0.2"], dtype=object),
        "grasp_type": np.full(6, grasp_type, dtype=object),
        # within the energy thresholds: the first two bowl grasps and the first hammer grasp (the others each miss one)
        "E_fc": np.asarray([0.1, 0.2, 0.5, 0.1, 0.1, 0.1], np.float32), "E_dis": np.asarray([0.001, 0.002, 0.001, 0.001, 0.001, 0.006], np.float32),
        "E_pen": np.asarray([0.0, 0.0005, 0.0, 0.002, 0.0, 0.0], np.float32), "penetration_mm": np.asarray([1.0, 1.2, 1.4, 3.0, 0.5, 0.1], np.float32),
    })  # fmt: skip
    write_grasp_store(path / "all_grasps.zarr", grasps, {})


def test_rows_and_table(tmp_path, benchmark_script):
    script = benchmark_script("grasp_types")
    _store(tmp_path)
    rows = script.per_object_rows(tmp_path, "pinch", seed=3)
    bowl, hammer = rows
    assert (bowl["family"], bowl["attempts"], bowl["held"], bowl["held_six"], bowl["distinct"]) == ("bowl", 4, 3, 1, 2)
    assert (bowl["seed"], bowl["passing"], hammer["passing"]) == (3, 2, 1)
    assert (bowl["passing_held"], bowl["distinct_passing"], hammer["passing_held"]) == (2, 2, 0)
    assert bowl["depths_mm"] == [1.0, 1.2, 1.4] and bowl["failures"] == {"initial_penetration": 1}
    assert (hammer["held"], hammer["distinct"], hammer["failures"]) == (0, 0, {"dropped": 2})
    lines = script.table(rows, ["bowl", "hammer"], ["pinch"])
    assert len(lines) == 2 + 3 and "| bowl | pinch | 1 | 2/4 = 50% (" in lines[2] and "| 3/4 = 75% (" in lines[2]
    assert lines[2].split("|")[7].startswith(" 2/4 = 50% (") and "| 2.0 | 2.0 | 1.20 / 1.36 |" in lines[2]
    assert lines[-1].startswith("| **all objects** | pinch | 2 | 3/6 = 50% (")
    # a second seed of the same objects: still two objects, distinct held averaged over objects and seeds
    again = script.table(rows + [{**r, "seed": 4, "distinct": 0} for r in rows], ["bowl", "hammer"], ["pinch"])
    assert "| bowl | pinch | 1 | 4/8 = 50% (" in again[2] and "| 1.0 | 2.0 | 1.20 / 1.40 |" in again[2]


def test_a_run_that_recorded_another_type_is_refused(tmp_path, benchmark_script):
    _store(tmp_path, grasp_type="power")
    with pytest.raises(SystemExit, match="recorded grasp types"):
        benchmark_script("grasp_types").per_object_rows(tmp_path, "pinch")
