"""benchmarks/experiments/grasp_check_meshes.py: per-mesh counts read from a dexlite grasp output folder."""

import numpy as np
import pytest

from dexlite_pipeline.io.grasp_store import GraspSet, write_grasp_store


def test_counts_per_mesh_and_source(tmp_path, benchmark_script):
    # mug: model 2 grasps (1 held), optimization 3 (2 held, near-duplicates: one distinct label); box: model only, none held
    objects = ["user-mug"] * 5 + ["user-box"] * 2
    sources = ["model", "model", "optimization", "optimization", "optimization", "model", "model"]
    held = [1, 0, 1, 1, 0, 0, 0]
    labels = [0, -1, 1, 1, -1, -1, -1]
    grasps = GraspSet({
        "hand_pose": np.zeros((7, 28), np.float32), "object_id": np.asarray(objects, dtype=object), "scale": np.ones(7, np.float32),
        "lift_success": np.asarray(held, bool), "distinct_label": np.asarray(labels, np.int64), "source": np.asarray(sources, dtype=object),
        "six_dir_success": np.asarray([1, 1, 0, 1, 1, 0, 0], bool),  # held or not: only held and passed counts
        "initial_penetration_mm": np.asarray([0.5, 3.0, 1.5, 1.0, 2.5, 0.0, 0.0], np.float32),
    })  # fmt: skip
    write_grasp_store(tmp_path / "all_grasps.zarr", grasps, {})
    counts = benchmark_script("grasp_check_meshes").per_mesh_counts(tmp_path)
    assert counts["user-mug"] == {"attempts": 5, "held": 3, "distinct": 2, "six": 2, "held_start_mm": [0.5, 1.5, 1.0],
                                  "model": "1/2", "optimization": "2/3"}
    assert counts["user-box"] == {"attempts": 2, "held": 0, "distinct": 0, "six": 0, "held_start_mm": [], "model": "0/2",
                                  "optimization": "-"}


def test_seed_runs_take_config_sections_and_the_kitchen_set(benchmark_script):
    module = benchmark_script("grasp_check_meshes")
    args, extra = module.parse_seed_runs(["out", "--set", "kitchen", "--config-json", '{"sample": {"type_mix": "even"}}', "--",
                                          "--n", "32"], "d", mesh_sets=True)
    assert (args.mesh_set, args.config_json, args.seeds, extra) == ("kitchen", {"sample": {"type_mix": "even"}}, [0, 1, 2], ["--n", "32"])
    with pytest.raises(SystemExit):
        module.parse_seed_runs(["out", "--set", "kitchen"], "d")  # --set is the check meshes' only
