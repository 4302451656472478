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


def test_no_output_that_says_held_starts_deeper_than_the_cap(complete_run):
    """Every store the run wrote with lift results (lift validation, the loop's rounds, the evaluation): a held grasp
    started at most ``lift.max_initial_penetration_m`` inside its object, by the penetration measure."""
    import yaml

    config = yaml.safe_load((complete_run.workdir / "config.yaml").read_text()) if (complete_run.workdir / "config.yaml").exists() else {}
    cap_mm = 1000.0 * float((config.get("lift") or {}).get("max_initial_penetration_m", 0.002))
    checked = 0
    for path in sorted((complete_run.workdir / "results").rglob("*.zarr")):
        if "assets" in path.parts:  # an object's arrays, not a grasp store
            continue
        store = read_grasp_store(path)
        if "lift_success" not in store.arrays or "initial_penetration_mm" not in store.arrays:
            continue
        held = np.asarray(store.arrays["lift_success"], bool)
        depth = np.asarray(store.arrays["initial_penetration_mm"], np.float64)
        assert (depth[held] <= cap_mm + 1e-4).all(), f"{path}: a held grasp starts {depth[held].max():.2f} mm deep (cap {cap_mm} mm)"
        checked += int(held.sum())
    assert checked > 0, "the run should hold some grasps"
