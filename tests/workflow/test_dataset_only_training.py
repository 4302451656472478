"""A run whose every training object comes from the grasp dataset (dry runs): training does not wait for the held-out
objects' optimization; a run with any other source of training objects still trains on its lift-validated shards."""

from __future__ import annotations

import subprocess

from workflow_harness import REPO, planned_commands, snakemake_command, snakemake_env, tiny_config, write_config


def _planned(tmp_path, **objects) -> dict[str, list[str]]:
    config = tiny_config(tmp_path / "meshes")
    config["dexgraspnet"] = {**config["dexgraspnet"], "root": ""}
    config["dataset"] = {**config.get("dataset", {}), "root": str(REPO / "dataset")}
    config["objects"] = {**config["objects"], "dataset_objects": True, "mesh_dirs": [], "builtin_count": 0, "household_count": 0,
                         "household_benchmark_objects": 2, **objects}
    write_config(tmp_path / "run", config)
    command = snakemake_command(tmp_path / "run", "--dry-run", "--printshellcmds", "--cores", "1", "results/model/cvae.pt")
    done = subprocess.run(command, env=snakemake_env(), capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
    return planned_commands(done.stdout + done.stderr)


def test_training_on_the_dataset_alone_does_not_wait_for_the_heldout_optimization(tmp_path):
    commands = _planned(tmp_path)
    assert set(commands) == {"prepare_objects", "stability_filter", "dataset_grasps", "train_cvae"}
    assert "--lift results/dataset/shard_000.zarr" in commands["train_cvae"][0]
    assert "results/lift/" not in commands["train_cvae"][0]


def test_any_other_training_source_keeps_the_lift_validated_shards(tmp_path):
    commands = _planned(tmp_path, household_count=2)
    assert {"optimize_grasps", "lift_validate", "dataset_grasps", "train_cvae"} <= set(commands)
    assert "--lift results/lift/shard_000.zarr" in commands["train_cvae"][0]
