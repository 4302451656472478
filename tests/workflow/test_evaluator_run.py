"""The learned evaluator in the tiny run: it trains on the training objects' simulated grasps only, and the ranked
rows come out on the held-out objects, as many per object as the evaluation simulates, scored, and measured."""

from __future__ import annotations

import json
from collections import Counter

import numpy as np
import pandas as pd

from dexlite_pipeline.io.grasp_store import read_grasp_store


def _splits(workdir):
    """Object id -> split over the run's prepared objects (its own and the DexGraspNet import's)."""
    from dexlite_pipeline.objects.assets import object_splits

    return object_splits([workdir / "results" / "objects", workdir / "results" / "dexgraspnet" / "objects"], ok_only=False)


def test_the_evaluator_trains_on_training_objects_only(complete_run):
    workdir = complete_run.workdir
    splits = _splits(workdir)
    facts = json.loads((workdir / "results" / "evaluator" / "training.json").read_text())
    assert facts["examples"] > 0 and facts["train_object_ids"]
    assert all(splits[o] == "train" for o in facts["train_object_ids"]), facts["train_object_ids"]
    assert facts["sources"]["on_generator"]["grasps"] > 0  # the model's own samples, simulated
    # the record holds the settings the training read, as the run set them (not other stages' keys at their defaults)
    section = complete_run.config["evaluator"]
    assert facts["config"]["evaluator"] == {k: section[k] for k in ("epochs", "hand_points_per_shape", "validation_fraction")}
    for path in sorted((workdir / "results" / "evaluator").glob("examples_*.zarr")):
        store = read_grasp_store(path)
        assert all(splits[str(o)] == "train" for o in store.object_id), f"{path}: a held-out object's samples"
        assert "raw_hand_pose" in store.arrays and "lift_success" in store.arrays


def test_ranked_rows_match_the_unranked_count_and_are_measured(complete_run):
    workdir = complete_run.workdir
    splits = _splits(workdir)
    # as many ranked rows per object as the evaluation simulates of the unranked ones, each the best of pool_factor
    per_object = min(complete_run.config["sample"]["synthesis_grasps_per_object"], complete_run.config["evaluate"]["grasps_per_object"])
    ranked_objects, raw_objects = Counter(), Counter()
    for path in sorted((workdir / "results" / "sample").glob("shard_*.zarr")):
        store = read_grasp_store(path)
        method = store.arrays["method"].astype(str)
        score = np.asarray(store.arrays["evaluator_score"], np.float64)
        ranked = method == "cvae_ranked"
        assert np.isfinite(score[ranked]).all() and np.isfinite(score[method == "cvae_raw"]).all()
        assert np.isnan(score[(method != "cvae_raw") & ~ranked]).all()  # only pure syntheses are scored
        ranked_objects.update(store.object_id[ranked].astype(str))
        raw_objects.update(store.object_id[method == "cvae_raw"].astype(str))
    assert ranked_objects and set(ranked_objects) == set(raw_objects)
    assert all(splits[o] == "heldout" for o in ranked_objects)
    assert set(ranked_objects.values()) == {per_object}
    metrics = pd.read_csv(workdir / "results" / "eval" / "metrics.csv")
    rows = metrics.set_index("method")
    assert {"cvae_ranked", "cvae_ranked_post"} <= set(rows.index)
    assert rows.loc["cvae_ranked_post", "n_grasps"] == rows.loc["cvae_post", "n_grasps"]  # equal simulated attempts
    assert "evaluator_auc_held" in metrics.columns and rows.loc["cvae_post", "evaluator_scored"] > 0
    assert rows.loc["cvae_ranked_post", "seconds_per_grasp_by_stage"].startswith("ranking=")


def test_the_evaluation_measures_the_best_ranked_grasps(complete_run):
    """The evaluation's cap takes a ranked method's best-ranked grasps of each object (not a random draw of them)."""
    workdir = complete_run.workdir
    cap = complete_run.config["evaluate"]["grasps_per_object"]
    checked = 0
    for path in sorted((workdir / "results" / "eval" / "sim").glob("shard_*.zarr")):
        store = read_grasp_store(path)
        method = store.arrays["method"].astype(str)
        for name in ("cvae_ranked", "cvae_ranked_post"):
            mine = method == name
            for object_id in set(store.object_id[mine].astype(str)):
                ranks = np.sort(np.asarray(store.arrays["evaluator_rank"], np.float64)[mine & (store.object_id.astype(str) == object_id)])
                assert ranks.tolist() == list(range(len(ranks))) and len(ranks) <= cap, (name, object_id, ranks)
                checked += 1
    assert checked > 0
