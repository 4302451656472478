"""The lift test with a hand from its MJCF: the tests' three-finger hand in its own scene, with its own actuators."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from described_hands import FLAT_BOX_ID, FLAT_BOX_SCALE, cage_grasp, far_grasp, three_finger_hand, write_objects  # noqa: E402

from dexlite_pipeline.io.grasp_store import GraspSet  # noqa: E402
from dexlite_pipeline.objects.assets import load_asset  # noqa: E402
from dexlite_pipeline.sim.config import LiftConfig  # noqa: E402


@pytest.fixture(scope="module")
def setting(tmp_path_factory):
    root = write_objects(tmp_path_factory.mktemp("described_objects"))
    return three_finger_hand(tmp_path_factory.mktemp("hand")), root


def test_a_grasp_that_cages_the_box_holds_and_one_far_from_it_does_not(setting, one_torch_thread):
    from dexlite_pipeline.sim.lift import run_lift_tests

    hand, root = setting
    poses = np.stack([cage_grasp(), far_grasp()]).astype(np.float32)
    grasps = GraspSet({"hand_pose": poses, "object_id": np.array([FLAT_BOX_ID] * 2, dtype=object), "scale": np.full(2, FLAT_BOX_SCALE, np.float32)})
    out = run_lift_tests(grasps, [str(root)], LiftConfig(), hand=hand)
    assert out["lift_success"].tolist() == [True, False], out
    assert out["failure_reason"].tolist() == ["", "dropped"]
    assert out["lift_ratio"][0] > 0.95 and out["initial_penetration_mm"][0] < 0.1


def test_the_scene_drives_every_joint_with_the_hands_own_gains(setting):
    """One position actuator per joint in joint order: the file's own kp where it has one (f1_j1: 2), else lift.finger_kp;
    the hand's visual-free collision geoms only; a table when asked for."""
    from dexlite_pipeline.objects.rest_pose import SupportPlane
    from dexlite_pipeline.sim.described_scene import DescribedLiftScene

    hand, root = setting
    asset = load_asset(root, FLAT_BOX_ID)
    config = LiftConfig()
    scene = DescribedLiftScene.build_for(hand, asset.convex_paths, FLAT_BOX_SCALE, config, SupportPlane((0.0, 0.0, 1.0), 0.2))
    model = scene.model
    names = [model.actuator(a).name for a in range(model.nu)]
    assert names == [f"A_{name}" for name in hand.joint_names]
    expected = np.full(9, config.finger_kp)
    expected[hand.joint_names.index("f1_j1")] = 2.0
    assert np.allclose(model.actuator_gainprm[:, 0], expected) and np.allclose(model.actuator_biasprm[:, 1], -expected)
    assert np.allclose(model.actuator_ctrlrange, hand.joint_limits.numpy())
    assert len(scene.hand_geoms) == len(hand.description.shapes) and scene.table_geom >= 0
    assert scene.joint_qpos == slice(7, 16) and model.body_gravcomp[scene.palm_body] == 1.0


def test_the_squeeze_moves_the_touching_fingers_only(setting):
    """In the cage grasp the two fingers touch the box (within 5 mm) and close further (their first two joints are at
    their limits: the last one moves); the thumb, clear of it, stays."""
    from dexlite_pipeline.objects.assets import SdfBank
    from dexlite_pipeline.sim.squeeze import squeeze_targets

    hand, root = setting
    bank = SdfBank([load_asset(root, FLAT_BOX_ID)])
    pose = torch.as_tensor(cage_grasp(), dtype=torch.float32)[None]
    plan = squeeze_targets(hand, bank, pose, torch.full((1,), FLAT_BOX_SCALE), LiftConfig())
    delta = (plan.targets - pose[:, 6:])[0]
    assert plan.targets.shape == (1, 9)
    assert float(delta[2]) > 0 and float(delta[5]) > 0 and float(delta[6:].abs().max()) == 0.0
    assert bool((plan.targets[0] <= hand.joint_limits[:, 1]).all())
