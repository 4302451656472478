"""The evaluator's training on a run's stores: held-out objects never enter, post-optimized samples are judged by
their sampled pose, grasps never refined are left out with their reason, and the facts say what went in."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import trimesh

from dexlite_pipeline.evaluator.config import EvaluatorSection
from dexlite_pipeline.evaluator.training import as_examples, train_from_run
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store, write_grasp_store
from dexlite_pipeline.objects.assets import CATALOG_NAME

SPLITS = {"box": "train", "sphere": "train", "capsule": "train", "cylinder": "heldout"}


@pytest.fixture(scope="module")
def objects_dir(tmp_path_factory):
    """Four prepared objects and a catalog: three training objects, one held out."""
    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    root = tmp_path_factory.mktemp("objects")
    meshes = {
        "box": trimesh.creation.box(extents=(1.2, 0.9, 0.7)),
        "sphere": trimesh.creation.icosphere(subdivisions=2, radius=0.95),
        "capsule": trimesh.creation.capsule(height=1.0, radius=0.4),
        "cylinder": trimesh.creation.cylinder(radius=0.6, height=1.2),
    }
    for object_id, mesh in meshes.items():
        write_asset(mesh, object_id, root, AssetBuildSettings(sdf_resolution=12, surface_points=300), {"source": "test"}, convex_pieces=[mesh])
    pd.DataFrame({"object_id": list(SPLITS), "split": list(SPLITS.values()), "status": "ok"}).to_parquet(root / CATALOG_NAME)
    return root


def _poses(rng, count):
    pose = np.zeros((count, 28), np.float32)
    pose[:, :3] = rng.normal(0.0, 0.08, (count, 3))
    pose[:, 3:9] = [1, 0, 0, 0, 1, 0]
    return pose


def _lift_store(rng, per_object=12) -> GraspSet:
    """Optimization's lift shard: every object, the held-out one too (as a real run's shards hold it)."""
    ids = np.repeat(list(SPLITS), per_object).astype(object)
    return GraspSet({"hand_pose": _poses(rng, len(ids)), "object_id": ids, "scale": np.full(len(ids), 0.08, np.float32),
                     "lift_success": rng.random(len(ids)) < 0.7, "failure_reason": np.full(len(ids), "", dtype=object)})


def _example_store(rng, per_object=12) -> GraspSet:
    """On-generator examples: refined poses beside the sampled ones, two rows never refined."""
    ids = np.repeat(["box", "sphere", "capsule"], per_object).astype(object)
    raw = _poses(rng, len(ids))
    refined = raw + 0.01
    drop = np.full(len(ids), "", dtype=object)
    drop[:2] = "not_optimized"
    held = rng.random(len(ids)) < 0.3
    held[:2] = False
    refined[:2] = np.nan
    return GraspSet({"hand_pose": refined, "raw_hand_pose": raw, "object_id": ids, "scale": np.full(len(ids), 0.08, np.float32),
                     "lift_success": held, "six_dir_success": held & (rng.random(len(ids)) < 0.8), "drop_reason": drop})


def test_as_examples_judges_the_sampled_pose_and_marks_unrefined_rows():
    rng = np.random.default_rng(0)
    store = _example_store(rng)
    seen = as_examples(store)
    np.testing.assert_array_equal(seen.hand_pose, store.arrays["raw_hand_pose"])
    assert all(str(r).startswith("not_tested") for r in seen.arrays["failure_reason"][:2])
    assert not any(str(r) for r in seen.arrays["failure_reason"][2:])


def test_held_out_objects_never_reach_training(tmp_path, objects_dir):
    rng = np.random.default_rng(1)
    lift_path, example_path = str(tmp_path / "lift.zarr"), str(tmp_path / "examples.zarr")
    write_grasp_store(lift_path, _lift_store(rng), {})
    write_grasp_store(example_path, _example_store(rng), {})
    section = EvaluatorSection(enabled=True, epochs=2, hand_points_per_shape=2, validation_fraction=0.34)
    model, facts = train_from_run([lift_path], [example_path], [str(objects_dir)], section, seed=0, device="cpu")
    assert set(facts["train_object_ids"]) == {"box", "sphere", "capsule"}
    assert "cylinder" not in facts["fit_object_ids"] + facts["validation_object_ids"]
    assert facts["excluded"]["object not in object_ids"] == 12  # the held-out object's optimization grasps, counted
    assert facts["excluded"]["never simulated (not_tested)"] == 2
    lift = read_grasp_store(lift_path)
    expected = int((lift.object_id != "cylinder").sum()) + 36 - 2
    assert facts["examples"] == expected
    assert facts["sources"]["optimization"]["on_training_objects"] == 36
    assert facts["sources"]["on_generator"]["grasps"] == 36
    assert len(facts["history"]) == 2 and facts["best_epoch"] in (1, 2)
    assert model.config.hand_points_per_shape == 2
