"""The learned evaluator in the tiny run: it trains on the training objects' simulated grasps only, and the ranked
rows come out on the held-out objects, as many per object as the unranked ones, scored, and measured."""

from __future__ import annotations

import json
from collections import Counter

import numpy as np
import pandas as pd

from dexlite_pipeline.io.grasp_store import read_grasp_store


def _splits(workdir):
    catalog = pd.read_parquet(workdir / "results" / "objects" / "catalog.parquet")
    return dict(zip(catalog["object_id"].astype(str), catalog["split"].astype(str)))


def test_the_evaluator_trains_on_training_objects_only(complete_run):
    workdir = complete_run.workdir
    splits = _splits(workdir)
    facts = json.loads((workdir / "results" / "evaluator" / "training.json").read_text())
    assert facts["examples"] > 0 and facts["train_object_ids"]
    assert all(splits[o] == "train" for o in facts["train_object_ids"]), facts["train_object_ids"]
    assert facts["sources"]["on_generator"]["grasps"] > 0  # the model's own samples, simulated
    for path in sorted((workdir / "results" / "evaluator").glob("examples_*.zarr")):
        store = read_grasp_store(path)
        assert all(splits[str(o)] == "train" for o in store.object_id), f"{path}: a held-out object's samples"
        assert "raw_hand_pose" in store.arrays and "lift_success" in store.arrays


def test_ranked_rows_match_the_unranked_count_and_are_measured(complete_run):
    workdir = complete_run.workdir
    splits = _splits(workdir)
    per_object = complete_run.config["sample"]["synthesis_grasps_per_object"]
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
