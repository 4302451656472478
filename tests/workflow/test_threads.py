"""Threads each stage's jobs get from `snakemake --cores 2`, with and without the local profile
(a dry run of a fresh directory: the `--threads` that the `dexlite` commands would receive)."""

from __future__ import annotations

import shutil

import pytest
from workflow_harness import checkout, grasp_fixture, option_value, planned_commands, run_snakemake, tiny_config, write_config

# Stages that run once for all objects use every core; sharded stages one per job.
ALL_CORES_STAGES = {"prepare_objects", "stability_filter", "import_dexgraspnet", "train_cvae"}
SHARDED_STAGES = {"optimize_grasps", "curate", "lift_validate", "sample_grasps", "post_optimize"}


@pytest.mark.parametrize("profile", [None, "local"])
def test_every_stage_gets_its_threads_with_or_without_the_local_profile(tmp_path, profile):
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    (meshes / "box.obj").write_text("not read by a dry run\n")
    dexgraspnet = shutil.copytree(grasp_fixture(), tmp_path / "dexgraspnet")
    write_config(tmp_path / "run", tiny_config(meshes, dexgraspnet={"root": str(dexgraspnet)}))
    profile_args = ["--profile", str(checkout() / "profiles" / profile)] if profile else []

    output = run_snakemake(tmp_path / "run", "--dry-run", "--printshellcmds", *profile_args, "--cores", "2", "all")

    commands = planned_commands(output)
    threads = {rule: {option_value(c, "--threads") for c in cmds} for rule, cmds in commands.items() if "--threads" in cmds[0]}
    assert ALL_CORES_STAGES | SHARDED_STAGES <= set(threads)
    assert {rule: threads[rule] for rule in ALL_CORES_STAGES} == {rule: {"2"} for rule in ALL_CORES_STAGES}
    assert {rule: threads[rule] for rule in SHARDED_STAGES} == {rule: {"1"} for rule in SHARDED_STAGES}
