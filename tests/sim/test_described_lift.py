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


def test_the_scene_drives_every_joint_with_the_protocols_gain(setting):
    """One position actuator per joint in joint order, each with lift.finger_kp, also where the file has its own servo
    (f1_j1: kp 2, recorded in the drive); the hand's visual-free collision geoms only; a table when asked for."""
    from dexlite_pipeline.objects.rest_pose import SupportPlane
    from dexlite_pipeline.sim.described_scene import DescribedLiftScene, hand_drive

    hand, root = setting
    asset = load_asset(root, FLAT_BOX_ID)
    config = LiftConfig()
    scene = DescribedLiftScene.build_for(hand, asset.convex_paths, FLAT_BOX_SCALE, config, SupportPlane((0.0, 0.0, 1.0), 0.2))
    model = scene.model
    names = [model.actuator(a).name for a in range(model.nu)]
    assert names == [f"A_{name}" for name in hand.joint_names]
    expected = np.full(9, config.finger_kp)
    assert hand_drive(hand).kp[hand.joint_names.index("f1_j1")] == 2.0 and config.finger_kp != 2.0
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


def test_the_hands_contacts_take_mujocos_default_softness(setting):
    """LEAP's file makes the geoms of its main default class almost rigid (solref 1e-4 s, solimp 0.999) and damps its
    joints: in the lift scene the hand's, the object's and the table's geoms have MuJoCo's default contact parameters, as
    in the Shadow Hand's scene, the object's free joint is undamped, and friction is the protocol's."""
    from dexlite_pipeline.hand.described import DescribedHand
    from dexlite_pipeline.objects.rest_pose import SupportPlane
    from dexlite_pipeline.sim.described_scene import DescribedLiftScene

    _, root = setting
    leap = DescribedHand("leap")
    assert np.isclose(leap.description.mj_model().geom_solref[leap.description.shapes[0].geom, 0], 1e-4)
    config = LiftConfig()
    scene = DescribedLiftScene.build_for(leap, load_asset(root, FLAT_BOX_ID).convex_paths, FLAT_BOX_SCALE, config,
                                         SupportPlane((0.0, 0.0, 1.0), 0.2))
    model, hand = scene.model, scene.hand_geoms
    assert np.allclose(model.geom_solref[hand], [0.02, 1.0]) and np.allclose(model.geom_solimp[hand], [0.9, 0.95, 0.001, 0.5, 2.0])
    for others in (scene.object_geoms, [scene.table_geom]):
        assert np.allclose(model.geom_solref[others], [0.02, 1.0]) and np.allclose(model.geom_solimp[others], [0.9, 0.95, 0.001, 0.5, 2.0])
    free = model.jnt_dofadr[model.body_jntadr[scene.object_body]]
    assert np.allclose(model.dof_damping[free : free + 6], 0.0) and np.allclose(model.dof_frictionloss[free : free + 6], 0.0)
    assert np.allclose(model.geom_margin[hand], 0.0) and np.allclose(model.geom_friction[hand, 0], config.friction)
