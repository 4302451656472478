"""The data stages with config key ``hand`` naming the tests' three-finger hand (an MJCF file): optimize_grasps,
curate (its table depth, near-duplicate and force-closure checks with the hand's links and joints), lift_validate
(the hand's own scene) and model_batch (a model and an evaluator of the hand, the top-up with it; ``dexlite
dataset-add`` of the batch) run, and every store records the hand (its file and SHA-256, its joint names, 15-number
poses); stores and models of another hand are refused in one line. ``dexlite lift-test``, ``energy`` and ``render`` take
a store's own hand. Tiny budgets: a test of the wiring, not of the grasps."""

from __future__ import annotations

import hashlib
import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from described_hands import FLAT_BOX_ID, FLAT_BOX_SCALE, one_line_cli_error, untrained_model_and_evaluator, write_objects  # noqa: E402
from three_finger import write_three_finger  # noqa: E402

from dexlite_pipeline.cli import main  # noqa: E402
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store, write_grasp_store  # noqa: E402

TINY = {
    "seed": 1, "device": "cpu", "shards": 1,
    "energy": {"object_point_spacing_m": 0.004},
    "optimize_grasps": {"grasps_per_object": 6, "scales": [FLAT_BOX_SCALE], "batch_size": 8, "annealing": {"iterations": 20},
                        "final_contact_samples": 8, "contact_search_every": 0},
    # every grasp passes the energy thresholds, so that the later steps see grasps (the wiring is tested, not the grasps)
    "curate": {"thresholds": {"max_e_fc": 1e6, "max_e_dis_m": 10.0, "max_e_pen_m": 10.0}, "force_closure": False},
}  # fmt: skip


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The three stages run once through the command line: the optimized, curated and lift-tested stores."""
    root = tmp_path_factory.mktemp("hand_stages")
    objects = write_objects(root / "objects")
    pd.DataFrame({"object_id": [FLAT_BOX_ID], "source": "test", "file": "", "watertight": True, "volume": 0.624, "n_convex_pieces": 1,
                  "status": "ok", "reason": "", "split": "train"}).to_parquet(objects / "catalog.parquet")
    # the flat box (1.3 x 1.2 x 0.4 normalized) lies flat, its table 0.2 below its origin per unit scale
    pd.DataFrame({"object_id": [FLAT_BOX_ID], "lateral_displacement_m": 0.0, "rotation_deg": 0.0, "stable": True, "reason": "",
                  "support_nx": 0.0, "support_ny": 0.0, "support_nz": 1.0, "support_offset": 0.2}).to_parquet(root / "stability.parquet")
    xml = write_three_finger(root)
    config = json.dumps({**TINY, "hand": str(xml)})
    common = ["--stability", str(root / "stability.parquet"), "--objects", str(objects), "--threads", "1"]
    assert main(["optimize-grasps", "--config-json", config, "--shard", "000", "--out", str(root / "optimized.zarr"), *common]) == 0
    assert main(["curate", "--step", "curate", "--shard", "0", "--config-json", config, "--optimized-grasps", str(root / "optimized.zarr"),
                 "--out", str(root / "curated.zarr"), "--summary-out", str(root / "summary.csv"), *common]) == 0
    assert main(["lift-validate", "--config-json", config, "--grasps", str(root / "curated.zarr"), "--shard", "000",
                 "--out", str(root / "lift.zarr"), *common]) == 0
    return root, xml, objects, common


def test_the_stages_run_with_the_hand_and_every_store_records_it(run):
    root, xml, _, _ = run
    sha = hashlib.sha256(xml.read_bytes()).hexdigest()
    joints = [f"{f}_j{k}" for f in ("f1", "f2", "th") for k in range(3)]
    stores = {name: read_grasp_store(root / f"{name}.zarr") for name in ("optimized", "curated", "lift")}
    assert len(stores["optimized"]) == 6 and 0 < len(stores["curated"]) <= 6 and len(stores["lift"]) == len(stores["curated"])
    for name, store in stores.items():
        assert store.hand_pose.shape[1] == 15, name
        assert (store.attrs["hand"], store.attrs["hand_sha256"], store.attrs["joint_names"]) == (str(xml), sha, joints), name
    assert set(stores["optimized"].arrays["grasp_type"]) == {"power"}
    lifted = stores["lift"]
    assert np.isfinite(lifted.arrays["lift_ratio"]).any() and "table_depth_mm" in lifted.arrays
    assert not any(str(r).startswith("invalid_grasp") for r in lifted.arrays["failure_reason"])


def test_curation_checks_force_closure_with_the_hands_links(run, tmp_path):
    root, xml, _, common = run
    config = json.dumps({**TINY, "hand": str(xml), "curate": {**TINY["curate"], "force_closure": True}})
    assert main(["curate", "--step", "curate", "--shard", "0", "--config-json", config, "--optimized-grasps", str(root / "optimized.zarr"),
                 "--out", str(tmp_path / "fc.zarr"), "--summary-out", str(tmp_path / "fc.csv"), *common]) == 0
    kept = read_grasp_store(tmp_path / "fc.zarr")
    summary = pd.read_csv(tmp_path / "fc.csv")
    assert int(summary["n_input"].sum()) == 6 and "dropped_force_closure" in summary
    assert int(summary["dropped_force_closure_unknown"].sum()) == 0  # every grasp's ε computed with the three-finger hand
    assert (kept.arrays["force_closure_epsilon"] > 0).all() and kept.attrs["hand"] == str(xml)


def test_stores_of_another_hand_are_refused_in_one_line(run, tmp_path, capsys):
    root, xml, _, common = run
    shadow = GraspSet({"hand_pose": np.zeros((1, 28), np.float32), "object_id": np.array([FLAT_BOX_ID], dtype=object),
                       "scale": np.full(1, FLAT_BOX_SCALE, np.float32)})
    write_grasp_store(tmp_path / "shadow.zarr", shadow)
    config = json.dumps({**TINY, "hand": str(xml)})
    capsys.readouterr()
    code = main(["curate", "--step", "curate", "--shard", "0", "--config-json", config, "--optimized-grasps", str(root / "optimized.zarr"),
                 "--optimized-grasps", str(tmp_path / "shadow.zarr"), "--out", str(tmp_path / "mixed.zarr"),
                 "--summary-out", str(tmp_path / "mixed.csv"), *common])
    error = capsys.readouterr().err.strip()
    assert code == 2 and len(error.splitlines()) == 1 and "shadow.zarr" in error and "hand shadow" in error and str(xml) in error
    code = main(["lift-validate", "--config-json", json.dumps({**TINY, "hand": "shadow"}), "--grasps", str(root / "curated.zarr"),
                 "--shard", "000", "--out", str(tmp_path / "lift.zarr"), *common])
    error = capsys.readouterr().err.strip()
    assert code == 2 and len(error.splitlines()) == 1 and "curated.zarr" in error and "hand shadow" in error
    assert not (tmp_path / "mixed.zarr").exists() and not (tmp_path / "lift.zarr").exists()


def test_dexlite_lift_test_tests_a_store_with_its_own_hand(run, tmp_path):
    root, xml, objects, _ = run
    assert main(["lift-test", str(root / "curated.zarr"), "--objects", str(objects), "--out", str(tmp_path / "again.zarr"), "--threads", "1"]) == 0
    again, staged = read_grasp_store(tmp_path / "again.zarr"), read_grasp_store(root / "lift.zarr")
    assert again.attrs["hand"] == str(xml) and again.hand_pose.shape[1] == 15
    assert np.array_equal(again.arrays["lift_success"], staged.arrays["lift_success"])  # the stage's test, with the same hand


def test_energy_scores_a_store_with_its_own_hand_and_render_draws_it(run, tmp_path, capsys):
    root, xml, objects, _ = run
    assert main(["energy", str(root / "curated.zarr"), "--out", str(tmp_path / "e.zarr"), "--objects", str(objects), "--device", "cpu"]) == 0
    scored, curated = read_grasp_store(tmp_path / "e.zarr"), read_grasp_store(root / "curated.zarr")
    assert scored.attrs["hand"] == str(xml) and scored.hand_pose.shape == curated.hand_pose.shape == (len(curated), 15)
    assert (scored.arrays["energy_failure_reason"] == "").all()
    for name in ("E_fc", "E_dis", "E_pen", "E_spen", "E_joints", "E_total", "penetration_mm"):
        assert np.isfinite(scored.arrays[name]).all(), name
    assert ((scored.arrays["contact_index"] >= 0) & (scored.arrays["contact_index"] < 110)).all()  # among the hand's 110 candidates
    assert main(["render", str(root / "curated.zarr"), "--index", "0", "--out", str(tmp_path / "r.png"), "--objects", str(objects)]) == 0
    assert (tmp_path / "r.png").stat().st_size > 0  # the store's own hand, drawn (tests/report/test_other_hand_render.py)

    (tmp_path / "edited").mkdir()
    edited = write_three_finger(tmp_path / "edited")  # a store whose hand file changed since: refused in one line
    from dexlite_pipeline.hand.choice import hand_record

    write_grasp_store(tmp_path / "edited.zarr", GraspSet(curated.arrays, {**curated.attrs, **hand_record(str(edited))}))
    edited.write_text(edited.read_text() + "<!-- edited -->\n")
    error = one_line_cli_error(capsys, ["energy", str(tmp_path / "edited.zarr"), "--out", str(tmp_path / "e2.zarr"), "--objects", str(objects)])
    assert f"the hand file {edited} and {tmp_path / 'edited.zarr'} name hand {edited} with different file contents" in error
    assert not (tmp_path / "e2.zarr").exists()


def test_model_batch_makes_a_batch_of_the_hand_that_dataset_add_takes(run, tmp_path, capsys):
    """model_batch with an untrained model and evaluator of the hand: the model's grasps, then a top-up batch (the object
    is short of distinct held grasps), all with 15-number poses, lift- and six-direction-tested in the hand's scene; the
    store records the hand, and dataset-add makes the run a batch of a dataset of that hand. A model of another hand
    is refused in one line naming the key."""
    from dexlite_pipeline.dataset import load_dataset

    root, xml, objects, _ = run
    results = tmp_path / "results"  # a run's results folder: what dataset-add reads
    shutil.copytree(objects, results / "objects")
    (results / "stability").mkdir()
    shutil.copy(root / "stability.parquet", results / "stability" / "stability.parquet")
    model, evaluator = untrained_model_and_evaluator(tmp_path, str(xml))
    config = {**TINY, "hand": str(xml), "sample": {"scales": [FLAT_BOX_SCALE]}, "post_optimize": {"annealing": {"iterations": 10}},
              "evaluator": {"pool_factor": 2},
              "model_batch": {"model": str(model), "evaluator": str(evaluator), "grasps_per_object": 2, "min_distinct": 99, "top_up_batches": 1}}
    out = results / "model_batch" / "shard_000.zarr"
    stage = ["model-batch", "--shard", "000", "--stability", str(results / "stability" / "stability.parquet"), "--objects", str(results / "objects"),
             "--threads", "1"]  # fmt: skip
    assert main([*stage, "--config-json", json.dumps(config), "--out", str(out)]) == 0
    made = read_grasp_store(out)
    sources = np.asarray(made.arrays["source"]).astype(str)
    assert made.hand_pose.shape == (4, 15) and np.isfinite(made.hand_pose).all()
    assert sorted(sources) == ["model", "model", "optimization", "optimization"] and made.attrs["topped_up_objects"] == [FLAT_BOX_ID]
    assert (made.attrs["hand"], made.attrs["hand_sha256"]) == (str(xml), hashlib.sha256(xml.read_bytes()).hexdigest())
    assert made.attrs["joint_names"] == [f"{f}_j{k}" for f in ("f1", "f2", "th") for k in range(3)]
    assert {"lift_success", "six_dir_success", "evaluator_score"} <= set(made.arrays)
    empty = tmp_path / "empty.zarr"  # the second of two shards holds no object: no grasps, of the hand's width
    assert main([*stage[:1], "--shard", "001", *stage[3:], "--config-json", json.dumps({**config, "shards": 2}), "--out", str(empty)]) == 0
    assert read_grasp_store(empty).hand_pose.shape == (0, 15) and read_grasp_store(empty).attrs["hand"] == str(xml)

    assert main(["dataset-add", str(results), "--dataset", str(tmp_path / "dataset")]) == 0
    stored, rows = load_dataset(tmp_path / "dataset")
    assert stored.hand_pose.shape == (4, 15) and stored.attrs["hand"] == str(xml) and rows["object_id"].tolist() == [FLAT_BOX_ID]
    assert sorted(np.asarray(stored.arrays["source"]).astype(str)) == sorted(sources)

    (tmp_path / "shadow").mkdir()
    shadow_model = untrained_model_and_evaluator(tmp_path / "shadow", "shadow")[0]
    refused = {**config, "model_batch": {**config["model_batch"], "model": str(shadow_model)}}
    error = one_line_cli_error(capsys, [*stage, "--config-json", json.dumps(refused), "--out", str(tmp_path / "refused.zarr")])
    assert error == (f"dexlite model-batch: error: model_batch.model: {shadow_model}: a model of hand shadow, this run's hand is {xml}: "
                     f"train a model for hand {xml} (config key hand)")
    assert not (tmp_path / "refused.zarr").exists()
