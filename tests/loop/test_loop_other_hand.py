"""The data loop with a hand from its MJCF (the tests' three-finger hand, poses of 6 + 9 numbers): round 0's set, then one
round through the CLI (sample, post-optimize, validate, merge, train, summary) on the box and the sphere, every store and
the round's model recording the hand; a store of another hand refused in one line."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "model"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from described_hands import one_line_cli_error  # noqa: E402
from test_other_hands import POSE_WIDTH, THREE_FINGER_JOINTS, three_finger_model, three_finger_run  # noqa: E402,F401 (fixtures)

from dexlite_pipeline.cli import main  # noqa: E402
from dexlite_pipeline.io.grasp_store import read_grasp_store  # noqa: E402

LOOP = {"grasps_per_object": 2, "heldout_grasps_per_object": 1, "train_steps": 2, "post_iterations": 4, "six_directions": False}
THRESHOLDS = {"thresholds": {"max_e_fc": 1e9, "max_e_dis_m": 1e9, "max_e_pen_m": 1e9, "max_penetration_m": 1e9}}  # every refined grasp to the lift test


@pytest.fixture(scope="module")
def one_round(three_finger_run, three_finger_model):
    """Round 0's set from the lift shard and round 1's stores, model and summary row, every stage run by ``dexlite``."""
    root, _, objects, config = three_finger_run
    cfg = json.dumps({**config, "loop": LOOP, "curate": THRESHOLDS})
    where = ["--stability", str(root / "stability.parquet"), *objects, "--round", "1", "--shard", "000"]
    out = root / "loop"
    assert main(["loop-initial-set", "--lift", str(root / "lift.zarr"), *objects, "--out", str(out / "round_0.zarr")]) == 0
    for part in ("train", "heldout"):
        assert main(["loop-sample", "--config-json", cfg, "--model", str(three_finger_model), *where, "--part", part,
                     "--out", str(out / f"{part}_sample.zarr")]) == 0  # fmt: skip
        assert main(["loop-post-optimize", "--config-json", cfg, "--sample", str(out / f"{part}_sample.zarr"), *where, "--part", part,
                     "--out", str(out / f"{part}_post.zarr")]) == 0  # fmt: skip
        assert main(["loop-validate", "--config-json", cfg, "--grasps", str(out / f"{part}_post.zarr"), *where, "--part", part,
                     "--out", str(out / f"{part}_validated.zarr")]) == 0  # fmt: skip
    assert main(["loop-merge", "--config-json", cfg, "--previous", str(out / "round_0.zarr"), "--validated", str(out / "train_validated.zarr"),
                 "--round", "1", "--out", str(out / "round_1.zarr")]) == 0  # fmt: skip
    model = out / "cvae.pt"
    assert main(["loop-train", "--config-json", cfg, "--grasps", str(out / "round_1.zarr"), "--initial-model", str(three_finger_model),
                 "--stability", str(root / "stability.parquet"), *objects, "--round", "1", "--model", str(model),
                 "--history", str(out / "history.csv"), "--curves", str(out / "curves.png")]) == 0  # fmt: skip
    assert main(["loop-summary", "--config-json", cfg, "--round", "1", "--grasps", str(out / "round_1.zarr"), "--heldout",
                 str(out / "heldout_validated.zarr"), "--cost", str(out / "train_validated.zarr"), "--model", str(model), *objects,
                 "--stability", str(root / "stability.parquet"), "--table", str(out / "table.csv"), "--row", str(out / "row.json")]) == 0  # fmt: skip
    # a shard without objects (the one training object is dealt to the other of two shards): an empty store of the hand
    two = json.dumps({**config, "shards": 2, "loop": LOOP})
    for shard in ("000", "001"):
        assert main(["loop-sample", "--config-json", two, "--model", str(three_finger_model), *where[:-2], "--shard", shard, "--part", "train",
                     "--out", str(out / f"two_{shard}.zarr")]) == 0  # fmt: skip
    return root, out, model


def test_a_round_of_another_hand_keeps_its_pose_length_and_records_it(three_finger_run, one_round):
    from dexlite_pipeline.model.checkpoint import load_checkpoint

    root, xml, _, _ = three_finger_run
    _, out, model = one_round
    initial = read_grasp_store(out / "round_0.zarr")
    lifted = read_grasp_store(root / "lift.zarr")
    held_on_box = lifted.arrays["lift_success"] & (lifted.object_id == "box")  # the held grasps of the one training object
    assert held_on_box.sum() > 0 and np.array_equal(initial.hand_pose, lifted.hand_pose[held_on_box])
    for name in ("round_0", "train_sample", "train_post", "train_validated", "heldout_validated", "round_1"):
        store = read_grasp_store(out / f"{name}.zarr")
        assert store.hand_pose.shape[1] == POSE_WIDTH, name
        assert store.attrs["hand"] == str(xml) and store.attrs["joint_names"] == THREE_FINGER_JOINTS, name
    sampled = read_grasp_store(out / "train_sample.zarr")
    assert len(sampled) == 2 and set(sampled.object_id) == {"box"}  # loop.grasps_per_object on the one training object
    merged = read_grasp_store(out / "round_1.zarr")
    assert len(merged) >= len(initial) and set(merged.arrays["round"].tolist()) <= {0, 1}
    checkpoint = load_checkpoint(model)[1]
    assert checkpoint["hand"] == str(xml) and checkpoint["joint_names"] == THREE_FINGER_JOINTS
    two = [read_grasp_store(out / f"two_{shard}.zarr") for shard in ("000", "001")]
    assert sorted(len(store) for store in two) == [0, 2] and all(store.hand_pose.shape[1] == POSE_WIDTH for store in two)
    row = json.loads((out / "row.json").read_text())
    assert row["round"] == 1 and row["heldout_attempts"] == 1


def test_a_round_refuses_a_store_of_another_hand_in_one_line(three_finger_run, one_round, capsys):
    root, xml, objects, config = three_finger_run
    _, out, _ = one_round
    shadow = json.dumps({"diversity": {}, "scene": {"table": False}})  # no hand: the Shadow Hand's run
    error = one_line_cli_error(capsys, ["loop-merge", "--config-json", shadow, "--previous", str(out / "round_0.zarr"), "--validated",
                                     str(out / "train_validated.zarr"), "--round", "1", "--out", str(out / "refused.zarr")])
    assert f"{out / 'round_0.zarr'} holds grasps of hand {xml}, config key hand is shadow" in error
    error = one_line_cli_error(capsys, ["loop-validate", "--config-json", shadow, "--grasps", str(out / "train_post.zarr"), "--stability",
                                     str(root / "stability.parquet"), *objects, "--round", "1", "--part", "train", "--shard", "000",
                                     "--out", str(out / "refused.zarr")])  # fmt: skip
    assert f"holds grasps of hand {xml}, config key hand is shadow" in error
    assert not (out / "refused.zarr").exists()
