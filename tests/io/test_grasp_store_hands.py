"""Grasp stores of any hand: the pose length follows the recorded hand, its joint names travel with it, a store
without ``hand`` is the Shadow Hand's, stores of two hands are not combined, and the DexGraspNet-layout export
writes the hand's joint names."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dexlite_pipeline.hand.model import JOINT_NAMES
from dexlite_pipeline.io.grasp_store import (
    GraspSet, GraspStoreError, check_one_hand, empty_grasp_set, pose_width, read_grasp_store, store_hand, write_grasp_store,
)  # fmt: skip

ALLEGRO_JOINTS = [f"{finger}j{k}" for finger in ("ff", "mf", "rf", "th") for k in range(4)]  # 16 names, as Allegro's


def _grasps(width: int, n: int = 3) -> GraspSet:
    rng = np.random.default_rng(0)
    return GraspSet({"hand_pose": rng.normal(size=(n, width)).astype(np.float32), "object_id": np.array(["box"] * n, dtype=object),
                     "scale": np.full(n, 0.1, np.float32)})


def test_a_store_round_trips_an_allegro_pose_length_and_its_joint_names(tmp_path):
    attrs = {"hand": "allegro", "joint_names": ALLEGRO_JOINTS}
    grasps = _grasps(22)
    write_grasp_store(tmp_path / "a.zarr", grasps, attrs)
    back = read_grasp_store(tmp_path / "a.zarr")
    assert back.hand_pose.shape == (3, 22) and np.array_equal(back.hand_pose, grasps.hand_pose)
    assert back.attrs["hand"] == "allegro" and back.attrs["joint_names"] == ALLEGRO_JOINTS
    assert pose_width(back.attrs) == 22 and store_hand(back.attrs) == "allegro"
    assert empty_grasp_set(attrs).hand_pose.shape == (0, 22)


def test_the_pose_length_must_be_the_hands(tmp_path):
    with pytest.raises(GraspStoreError, match=r"expected \(N, 22\) for hand allegro"):
        write_grasp_store(tmp_path / "b.zarr", _grasps(28), {"hand": "allegro", "joint_names": ALLEGRO_JOINTS})
    with pytest.raises(GraspStoreError, match=r"expected \(N, 28\) for hand shadow"):
        write_grasp_store(tmp_path / "c.zarr", _grasps(22))
    with pytest.raises(GraspStoreError, match="must record its joint_names"):
        write_grasp_store(tmp_path / "d.zarr", _grasps(22), {"hand": "allegro"})
    assert not any(tmp_path.iterdir())


def test_a_store_without_hand_is_the_shadow_hands(tmp_path):
    write_grasp_store(tmp_path / "s.zarr", _grasps(28))
    back = read_grasp_store(tmp_path / "s.zarr")
    assert "hand" not in back.attrs and store_hand(back.attrs) == "shadow"
    assert back.attrs["joint_names"] == list(JOINT_NAMES) and pose_width(back.attrs) == 28


def test_stores_of_two_hands_are_refused_in_one_line_naming_both():
    shadow, allegro = {}, {"hand": "allegro", "joint_names": ALLEGRO_JOINTS}
    with pytest.raises(GraspStoreError) as error:
        check_one_hand([("optimized.zarr", allegro), ("imported.zarr", shadow)])
    message = str(error.value)
    assert "\n" not in message and "optimized.zarr" in message and "allegro" in message and "imported.zarr" in message and "shadow" in message
    # the same hand file at two paths is one hand (its bytes' SHA-256); a changed file is another
    a = {"hand": "/x/hand.xml", "hand_sha256": "ab", "joint_names": ["j"]}
    assert check_one_hand([("a", a), ("b", {**a, "hand": "/y/hand.xml"})])["hand_sha256"] == "ab"
    with pytest.raises(GraspStoreError):
        check_one_hand([("a", a), ("b", {**a, "hand_sha256": "cd"})])


def test_the_dexgraspnet_export_names_the_hands_joints(tmp_path):
    from dexlite_pipeline.io.dexgraspnet import export_dexgraspnet

    grasps = _grasps(22, n=2)
    grasps.attrs.update(hand="allegro", joint_names=ALLEGRO_JOINTS)
    export_dexgraspnet(grasps, tmp_path)
    entries = np.load(tmp_path / "dataset" / "box.npy", allow_pickle=True)
    qpos = entries[0]["qpos"]
    assert list(qpos) == [*ALLEGRO_JOINTS, "WRJRx", "WRJRy", "WRJRz", "WRJTx", "WRJTy", "WRJTz"]
    pose = grasps.hand_pose[0].astype(np.float64)
    assert qpos["ffj0"] == pose[6] and qpos["WRJTx"] == pose[0] and qpos["WRJRz"] == pose[5]
    record = json.loads((tmp_path / "hand.json").read_text())
    assert record["hand"] == "allegro" and record["joint_names"] == ALLEGRO_JOINTS
