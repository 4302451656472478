"""benchmarks/experiments/compare_runs.py: equal runs compare equal through renames; a moved value, a lost row or a changed array
is found; time columns are ignored."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import zarr

@pytest.fixture(scope="module")
def compare_runs(benchmark_script):
    return benchmark_script("compare_runs")


def write_run(root: Path, stage: str, method: str, protocol_column: str, success: float, seconds: float, poses: np.ndarray):
    (root / "evaluate").mkdir(parents=True)
    pd.DataFrame({"method": [method, "cvae_post"], "lift_success_rate": [success, 0.25], protocol_column: [0.9, 0.5],
                  "seconds_per_grasp": [seconds, 1.0]}).to_csv(root / "evaluate" / "metrics.csv", index=False)
    group = zarr.open_group(str(root / stage / "shard_000.zarr"), mode="w")
    group.create_array("hand_pose", data=poses)
    group.create_array("origin", data=np.array([method] * len(poses)))  # a text label renamed like a table cell
    group.create_array(protocol_column, data=np.ones(len(poses), bool))  # an array named like a table column


def test_equal_runs_through_renames_and_ignored_times(compare_runs, tmp_path, capsys):
    poses = np.arange(12, dtype=np.float32).reshape(3, 4)
    write_run(tmp_path / "a", "seed", "seed", "seed_protocol_rate", 0.5, 3.0, poses)
    write_run(tmp_path / "b", "optimized", "optimization", "writeup_protocol_rate", 0.5, 7.0, poses)
    renames = ["--rename-path", "seed=optimized", "--rename-value", "seed=optimization", "--rename-column", "seed_protocol=writeup_protocol"]
    assert compare_runs.main([str(tmp_path / "a"), str(tmp_path / "b"), *renames]) == 0
    out = capsys.readouterr().out
    assert "2 items compared, 0 differ" in out and "ignored ['seconds_per_grasp']" in out
    # without the renames the labels differ and the stores are unmatched
    assert compare_runs.main([str(tmp_path / "a"), str(tmp_path / "b")]) == 1


def test_a_moved_value_or_array_is_found(compare_runs, tmp_path, capsys):
    poses = np.arange(12, dtype=np.float32).reshape(3, 4)
    moved = poses.copy()
    moved[1, 2] = np.nextafter(moved[1, 2], np.float32(100))
    write_run(tmp_path / "a", "lift", "seed", "p", 0.5, 3.0, poses)
    write_run(tmp_path / "b", "lift", "seed", "p", 0.5000001, 3.0, moved)
    assert compare_runs.main([str(tmp_path / "a"), str(tmp_path / "b")]) == 1
    out = capsys.readouterr().out
    assert "column lift_success_rate: 1 cells differ" in out and "array hand_pose: 1 values differ" in out


def test_bad_rename_is_an_error(compare_runs, tmp_path):
    (tmp_path / "a").mkdir()
    with pytest.raises(SystemExit, match="OLD=NEW"):
        compare_runs.main([str(tmp_path / "a"), str(tmp_path / "a"), "--rename-path", "seed"])
