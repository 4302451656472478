"""`dexlite dataset-add` on the tiny run: its data stages become one dataset batch, and a second add is refused."""

from __future__ import annotations

import copy
import json
import subprocess
import sys

import numpy as np
import pytest

from workflow_harness import local_run_args, run_snakemake, snakemake_command, snakemake_env, write_config


def optimized_stores(run):
    from dexlite_pipeline.io.grasp_store import read_grasp_store

    return [read_grasp_store(p) for p in sorted((run / "results" / "optimized").glob("shard_*.zarr"))]


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
    # held-out objects were prepared turned (objects.heldout_yaw): left out, each named with its reason in the batch's record
    import pandas as pd

    catalog = pd.read_parquet(scratch_copy / "results" / "objects" / "catalog.parquet")
    turned = set(catalog.loc[catalog["turn_deg"] != 0, "object_id"])
    assert turned and turned == set(catalog.loc[catalog["split"] == "heldout", "object_id"])
    record = json.loads(next((dataset / "configs").glob("*.json")).read_text())
    assert set(record["left_out_objects"]) == turned & (set(lifted.object_id) | {o for s in optimized_stores(scratch_copy) for o in s.attrs["objects"]})
    assert all("turned" in reason for reason in record["left_out_objects"].values())
    assert all(f"left out {o}: " in done.stdout for o in record["left_out_objects"])  # and the command says so
    lifted = lifted.select(np.flatnonzero(~np.isin(lifted.object_id.astype(str), sorted(turned))))
    grasps, objects = load_dataset(dataset)
    assert len(grasps) == len(lifted)  # every lift-tested grasp, held or not
    np.testing.assert_array_equal(grasps.hand_pose, lifted.hand_pose)
    np.testing.assert_array_equal(np.asarray(grasps.arrays["lift_success"], bool), np.asarray(lifted.arrays["lift_success"], bool))
    held = np.asarray(grasps.arrays["lift_success"], bool)
    assert ((np.asarray(grasps.arrays["distinct_label"]) >= 0) == held).all()
    assert set(grasps.arrays["source"]) <= {"optimization", "dexgraspnet"}  # curation's origin of each grasp
    from dexlite_pipeline.io.grasp_store import grasp_types

    assert grasps.arrays["grasp_type"].tolist() == grasp_types(lifted).tolist()  # each grasp's type, stored
    optimized_ids = {o for store in optimized_stores(scratch_copy) for o in store.attrs["objects"]} - turned
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

    # A new run with the dataset as its training data: its training objects that the dataset holds are not optimized,
    # their grasps come from the dataset (every tested one, with its outcome), and the model trains on them.
    workdir = tmp_path / "from_dataset"
    config = copy.deepcopy(complete_run.config)
    config["dataset"] = {"root": str(dataset)}
    config["loop"] = {**config["loop"], "rounds": 0}
    write_config(workdir, config)
    run_snakemake(workdir, *local_run_args(), "results/model/cvae.pt", timeout_s=900)
    from dexlite_pipeline.objects.assets import object_splits

    splits = object_splits([workdir / "results" / "objects", workdir / "results" / "dexgraspnet" / "objects"])
    expected = {o for o in present_objects(dataset) if splits.get(o) == "train"}
    optimized = [read_grasp_store(p) for p in sorted((workdir / "results" / "optimized").glob("shard_*.zarr"))]
    skipped = {o for store in optimized for o in store.attrs["objects_from_dataset"]}
    from dexlite_pipeline.objects.assets import ok_object_ids
    from dexlite_pipeline.objects.stability import stable_object_ids

    optimizable = ok_object_ids(workdir / "results" / "objects") & stable_object_ids(workdir / "results" / "stability" / "stability.parquet")
    assert skipped == expected & optimizable and skipped
    assert not skipped & {o for store in optimized for o in store.attrs["objects"]}  # none of them optimized again
    from_dataset = GraspSet.concatenate([read_grasp_store(p) for p in sorted((workdir / "results" / "dataset").glob("shard_*.zarr"))])
    taken = {o for p in sorted((workdir / "results" / "dataset").glob("shard_*.zarr")) for o in read_grasp_store(p).attrs["objects"]}
    assert taken and taken <= expected
    dataset_grasps, _ = load_dataset(dataset, sorted(taken))
    assert len(from_dataset) == len(dataset_grasps)  # held or not
    assert not {str(o) for o in from_dataset.object_id} - expected  # never a held-out object's grasps
    assert (workdir / "results" / "model" / "cvae.pt").is_file()


@pytest.mark.slow
def test_a_model_made_batch_keeps_each_grasps_source_and_tops_up_the_short_objects(complete_run, scratch_copy, tmp_path):
    """Stage model_batch with the run's own model: every stable object gets the model's grasps, each object short of
    min_distinct distinct held grasps gets optimization from scratch, and dataset-add makes it a batch of kind model whose
    grasps keep their own source; a missing model file is refused in one line before anything runs."""
    import pandas as pd

    from dexlite_pipeline.dataset import load_dataset
    from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store

    config = copy.deepcopy(complete_run.config)
    config["lift"] = {**config.get("lift", {}), "six_directions": True}
    config["model_batch"] = {"model": str(scratch_copy / "results" / "model" / "cvae.pt"), "evaluator": "none", "grasps_per_object": 2,
                             "min_distinct": 2, "top_up_batches": 1}
    write_config(scratch_copy, config)
    run_snakemake(scratch_copy, *local_run_args(), "model_batch_all", timeout_s=900)
    shards = sorted((scratch_copy / "results" / "model_batch").glob("shard_*.zarr"))
    stores = [read_grasp_store(p) for p in shards]
    grasps = GraspSet.concatenate([s for s in stores if len(s)])
    objects = sorted(o for s in stores for o in s.attrs["objects"])
    topped_up = {o for s in stores for o in s.attrs["topped_up_objects"]}
    sources = np.asarray(grasps.arrays["source"]).astype(str)
    ids = grasps.object_id.astype(str)
    assert objects and sorted(set(ids)) == objects
    for object_id in objects:  # the model's 2 grasps each; optimization's only for the objects it topped up
        assert (sources[ids == object_id] == "model").sum() == 2
        assert ((sources[ids == object_id] == "optimization").sum() > 0) == (object_id in topped_up)
    assert {"lift_success", "six_dir_success", "initial_penetration_mm", "E_fc"} <= set(grasps.arrays)

    dataset = tmp_path / "dataset"
    command = [sys.executable, "-m", "dexlite_pipeline.cli", "dataset-add", str(scratch_copy / "results"), "--dataset", str(dataset)]
    done = subprocess.run(command, capture_output=True, text=True, cwd=scratch_copy)
    assert done.returncode == 0, done.stderr
    stored, rows = load_dataset(dataset)
    kept = ~np.isin(ids, sorted(set(ids) - set(rows["object_id"])))  # held-out objects (turned) are left out
    assert len(stored) == int(kept.sum())
    assert (np.asarray(stored.arrays["source"]).astype(str) == sources[kept]).all()
    batches = pd.read_csv(dataset / "batches.csv")
    assert batches["kind"].tolist() == ["model"]
    assert json.loads(batches["cpu_seconds"].iloc[0])["model_batch"] > 0
    assert json.loads((dataset / "configs" / "batch_0001.json").read_text())["model_batch"]["grasps_per_object"] == 2

    config["model_batch"]["model"] = str(tmp_path / "absent.pt")
    write_config(scratch_copy, config)
    refused = subprocess.run(snakemake_command(scratch_copy, "--cores", "1", "-n", "model_batch_all"), env=snakemake_env(None),
                             capture_output=True, text=True)
    assert refused.returncode != 0 and "model_batch.model" in refused.stdout + refused.stderr
