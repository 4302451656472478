"""Tabletop mode in the lift and six-direction tests: the object rests on its table, the hand must stay above it.

Controls (bars and hook grasps from ``bar_grasps``): a palm-up grasp from below the bar holds
when the bar floats and is rejected with ``hand_in_table`` when the bar lies on a table; a
grasp wholly above the table (the bar standing on its end, hooked round its middle) is
judged by the same physics in both modes and holds in both.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from bar_grasps import SCALE, grasp_set

from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix, matrix_to_euler_xyz
from dexlite_pipeline.objects.assets import load_asset
from dexlite_pipeline.sim.config import LiftConfig
from dexlite_pipeline.sim.lift import run_lift_tests
from dexlite_pipeline.sim.scene import LiftScene
from dexlite_pipeline.sim.simulator import GraspSimulator, _palm_quaternions
from dexlite_pipeline.objects.rest_pose import SupportPlane
from dexlite_pipeline.tabletop import HAND_IN_TABLE, SupportPlanes

LYING = SupportPlane((0.0, 0.0, 1.0), 0.25)  # the square bar lying flat: table 0.25 x scale below its axis
STANDING = SupportPlane((1.0, 0.0, 0.0), 1.0)  # the square bar standing on its end (its axis is the table normal)


def _from_below(pose: np.ndarray) -> np.ndarray:
    """The grasp turned 180 degrees about the bar's axis (x): the same hold, the palm now under the bar, facing up."""
    flip = torch.diag(torch.tensor([1.0, -1.0, -1.0]))
    out = pose.copy()
    out[:3] = (flip @ torch.as_tensor(pose[:3])).numpy()
    out[3:6] = matrix_to_euler_xyz(flip @ euler_xyz_to_matrix(torch.as_tensor(pose[None, 3:6]))).numpy()[0]
    return out


def test_grasp_from_below_holds_floating_and_is_rejected_on_the_table(objects_dir, hooks):
    below = _from_below(hooks["square_bar"])
    grasps = grasp_set([below], ["square_bar"])
    floating = run_lift_tests(grasps, [objects_dir], LiftConfig(), threads=1)
    assert floating["lift_success"].tolist() == [True], floating["failure_reason"]
    tabletop = run_lift_tests(grasps, [objects_dir], LiftConfig(), threads=1, support_planes=SupportPlanes({"square_bar": LYING}))
    assert tabletop["failure_reason"].tolist() == [HAND_IN_TABLE] and not tabletop["lift_success"][0]
    assert tabletop["table_depth_mm"][0] > 10.0  # the palm is under the bar, i.e. in the table
    assert np.isnan(tabletop["lift_ratio"][0])
    assert "table_depth_mm" not in floating


def test_grasp_above_the_table_holds_in_both_modes(objects_dir, hooks):
    grasps = grasp_set([hooks["square_bar"]], ["square_bar"])
    config = LiftConfig(six_directions=True)
    floating = run_lift_tests(grasps, [objects_dir], config, threads=1)
    tabletop = run_lift_tests(grasps, [objects_dir], config, threads=1, support_planes=SupportPlanes({"square_bar": STANDING}))
    assert floating["lift_success"].tolist() == [True]
    assert tabletop["lift_success"].tolist() == [True], tabletop["failure_reason"]
    assert tabletop["table_depth_mm"][0] == 0.0 and tabletop["lift_ratio"][0] > 0.9
    # The six pushes test the grip alone (the table's contacts are off), so they match the floating test.
    np.testing.assert_array_equal(tabletop["six_dir_passed"], floating["six_dir_passed"])


def test_object_starts_resting_on_the_table_and_rises_along_its_normal(objects_dir, hooks):
    """On the table gravity acts along -n; with the hand far away the object stays on the table (ratio 0), and the
    simulated scene holds the table at the object's lowest point."""
    asset = load_asset(objects_dir, "square_bar")
    config = LiftConfig()
    scene = LiftScene.build(asset.convex_paths, SCALE, config, STANDING)
    np.testing.assert_allclose(scene.model.opt.gravity, [-9.81, 0.0, 0.0])
    np.testing.assert_allclose(scene.model.geom_pos[scene.table_geom], [-SCALE * 1.0, 0.0, 0.0])
    away = hooks["square_bar"].copy()
    away[1] += 0.3  # the hand 30 cm to the side: nothing lifts the bar
    sim = GraspSimulator(scene, config)
    pose = away.astype(np.float64)
    ratio, reason = sim.lift(pose, _palm_quaternions(pose[None])[0], pose[6:])
    assert reason == "dropped" and abs(ratio) < 0.01  # rests on the table: neither lifted nor fallen
    assert scene.data.xipos[scene.object_body, 0] == pytest.approx(0.0, abs=0.003)


def test_floating_scene_is_unchanged(objects_dir):
    """Without a table the scene has no world geom and gravity along -z, as before tabletop mode."""
    scene = LiftScene.build(load_asset(objects_dir, "square_bar").convex_paths, SCALE, LiftConfig())
    assert scene.table_geom == -1 and scene.up is None
    np.testing.assert_array_equal(scene.model.opt.gravity, [0.0, 0.0, -9.81])
    assert not (np.asarray(scene.model.geom_bodyid) == 0).any()


def test_object_without_a_resting_pose_is_flagged_not_simulated(objects_dir, hooks):
    grasps = grasp_set([hooks["square_bar"], hooks["round_bar"]], ["square_bar", "round_bar"])
    result = run_lift_tests(grasps, [objects_dir], LiftConfig(), threads=1, support_planes=SupportPlanes({"square_bar": STANDING}))
    assert result["failure_reason"][1] == "invalid_grasp: no resting pose (tabletop mode)"
    assert math.isnan(result["lift_ratio"][1])
