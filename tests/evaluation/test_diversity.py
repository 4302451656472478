"""Distinct grasps: identical grasps count once, grasps apart in palm position or rotation count apart."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dexlite_pipeline.evaluation.diversity import (
    DiversityConfig,
    count_distinct_grasps,
    distinct_grasp_labels,
    first_of_each_cluster,
)


def pose(translation=(0.0, 0.0, 0.1), euler=(0.0, 0.0, 0.0), joints=0.2):
    p = np.zeros(28)
    p[:3] = translation
    p[3:6] = euler
    p[6:] = joints
    return p


def test_identical_grasps_count_once():
    assert count_distinct_grasps(np.stack([pose()] * 16)) == 1


def test_grasps_three_cm_apart_count_twice():
    assert count_distinct_grasps(np.stack([pose((0, 0, 0.1)), pose((0.03, 0, 0.1))])) == 2


def test_grasps_one_cm_apart_count_once():
    assert count_distinct_grasps(np.stack([pose((0, 0, 0.1)), pose((0.01, 0, 0.1))])) == 1


def test_rotation_threshold_reads_the_relative_angle():
    # the same palm position turned 25 deg about a tilted axis is one grasp; 35 deg is another
    base = Rotation.from_euler("xyz", [0.4, -0.3, 1.0])
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    near = (Rotation.from_rotvec(np.deg2rad(25) * axis) * base).as_euler("xyz")
    far = (Rotation.from_rotvec(np.deg2rad(35) * axis) * base).as_euler("xyz")
    b = base.as_euler("xyz")
    assert count_distinct_grasps(np.stack([pose(euler=b), pose(euler=near)])) == 1
    assert count_distinct_grasps(np.stack([pose(euler=b), pose(euler=far)])) == 2


def test_euler_wraparound_is_the_same_rotation():
    a = pose(euler=(np.pi - 1e-4, 0.0, 0.0))
    b = pose(euler=(-np.pi + 1e-4, 0.0, 0.0))
    assert count_distinct_grasps(np.stack([a, b])) == 1


def test_finger_angles_do_not_make_a_grasp_distinct():
    assert count_distinct_grasps(np.stack([pose(joints=0.1), pose(joints=1.2)])) == 1


def test_groups_never_share_a_cluster():
    poses = np.stack([pose()] * 4)
    labels = distinct_grasp_labels(poses, np.array(["a", "a", "b", "b"]))
    assert labels.tolist() == [0, 0, 1, 1]


def test_thresholds_are_settings():
    poses = np.stack([pose((0, 0, 0.1)), pose((0.03, 0, 0.1))])
    assert count_distinct_grasps(poses, translation_m=0.05) == 1
    with pytest.raises(ValueError, match="config.diversity"):
        DiversityConfig(distinct_translation_m=0.0)


def test_representatives_are_first_members():
    poses = np.stack([pose((0, 0, 0.1)), pose((0.005, 0, 0.1)), pose((0.1, 0, 0.1)), pose((0.0, 0, 0.1))])
    labels = distinct_grasp_labels(poses)
    assert labels.tolist() == [0, 0, 1, 0]
    assert first_of_each_cluster(labels).tolist() == [0, 2]
    assert count_distinct_grasps(np.zeros((0, 28))) == 0
