"""`dexlite dataset-add` on the tiny run: its data stages become one dataset batch, and a second add is refused."""

from __future__ import annotations

import copy
import subprocess
import sys

import numpy as np
import pytest

from workflow_harness import local_run_args, run_snakemake, write_config


@pytest.mark.slow
def test_a_runs_data_stages_become_one_batch_and_its_objects_are_not_added_twice(complete_run, scratch_copy, tmp_path):
    from dexlite_pipeline.dataset import dataset_summary, load_dataset, present_objects
    from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store

    config = copy.deepcopy(complete_run.config)
    config["lift"] = {**config.get("lift", {}), "six_directions": True}  # a dataset batch records both tests
    write_config(scratch_copy, config)
    lift_shards = sorted(str(p.relative_to(scratch_copy)) for p in (scratch_copy / "results" / "lift").glob("shard_*.zarr"))
    run_snakemake(scratch_copy, *local_run_args(), *lift_shards, timeout_s=900)
    dataset = tmp_path / "dataset"
    command = [sys.executable, "-m", "dexlite_pipeline.cli", "dataset-add", str(scratch_copy / "results"), "--dataset", str(dataset)]
    done = subprocess.run(command, capture_output=True, text=True, cwd=scratch_copy)
    assert done.returncode == 0, done.stderr

    lifted = GraspSet.concatenate([read_grasp_store(scratch_copy / p) for p in lift_shards])
    assert "six_dir_success" in lifted.arrays
    grasps, objects = load_dataset(dataset)
    assert len(grasps) == len(lifted)  # every lift-tested grasp, held or not
    np.testing.assert_array_equal(grasps.hand_pose, lifted.hand_pose)
    np.testing.assert_array_equal(np.asarray(grasps.arrays["lift_success"], bool), np.asarray(lifted.arrays["lift_success"], bool))
    held = np.asarray(grasps.arrays["lift_success"], bool)
    assert ((np.asarray(grasps.arrays["distinct_label"]) >= 0) == held).all()
    assert set(grasps.arrays["source"]) <= {"optimization", "dexgraspnet"}  # curation's origin of each grasp
    optimized = [read_grasp_store(p) for p in (scratch_copy / "results" / "optimized").glob("shard_*.zarr")]
    optimized_ids = {o for store in optimized for o in store.attrs["objects"]}
    # every optimized object, with or without a held grasp, and every object with a tested grasp (the import's too)
    assert set(objects["object_id"]) == optimized_ids | set(lifted.object_id)
    assert objects.set_index("object_id").loc[sorted(optimized_ids), "support_nz"].notna().all()  # their resting poses (tabletop)
    summary = dataset_summary(dataset)
    assert summary["per_batch"][0]["cpu_seconds"]["optimize_grasps"] > 0
    card = (dataset / "CARD.md").read_text()
    assert "held: MuJoCo lift test" in card

    before = {p.name: p.read_bytes() for p in sorted(dataset.rglob("*")) if p.is_file()}
    again = subprocess.run(command, capture_output=True, text=True, cwd=scratch_copy)
    assert again.returncode == 2
    assert len(again.stderr.strip().splitlines()) == 1 and sorted(present_objects(dataset))[0] in again.stderr
    assert {p.name: p.read_bytes() for p in sorted(dataset.rglob("*")) if p.is_file()} == before  # nothing written
