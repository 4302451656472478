"""What the tiny workflow trains on: the committed grasp fixture's grasps that hold in the run's own lift test."""

from __future__ import annotations

import numpy as np
from sample_data import FIXTURE_HELDOUT_OBJECT, FIXTURE_TRAIN_OBJECT

from dexlite_pipeline.io.grasp_store import read_grasp_store


def test_the_tiny_run_trains_on_fixture_grasps_that_hold(complete_run):
    stores = [read_grasp_store(path) for path in sorted((complete_run.workdir / "results" / "lift").glob("*.zarr"))]
    assert stores, "the tiny run wrote no lift results"
    objects = np.concatenate([store.object_id for store in stores]).astype(str)
    held = np.concatenate([store.arrays["lift_success"] for store in stores]).astype(bool)
    assert held[objects == FIXTURE_TRAIN_OBJECT].sum() >= 1, f"no grasp of {FIXTURE_TRAIN_OBJECT} held in the tiny run: nothing to train on"
    assert FIXTURE_HELDOUT_OBJECT not in set(objects)  # held out: never curated for training
    assert (complete_run.workdir / "results" / "model" / "cvae.pt").is_file()
