"""Distinct grasps: identical grasps count once, grasps apart in palm position or rotation count apart; surface coverage."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dexlite_pipeline.evaluation.diversity import (
    DiversityConfig,
    count_distinct_grasps,
    distinct_grasp_labels,
    first_of_each_cluster,
    surface_coverage,
    surface_patch_labels,
    touched_patches,
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


# ---------------------------------------------------------------- surface coverage

# Six surface samples on the axes (a unit octahedron's vertices): with six patches, each its own.
AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)


def test_patches_are_farthest_point_centres_with_nearest_assignment():
    assert sorted(surface_patch_labels(AXES, 6).tolist()) == list(range(6))
    # two tight clusters far apart: two patches, one per cluster, whatever the order of the samples
    rng = np.random.default_rng(0)
    left, right = rng.normal([-1, 0, 0], 0.01, (20, 3)), rng.normal([1, 0, 0], 0.01, (30, 3))
    labels = surface_patch_labels(np.concatenate([left, right]), 2)
    assert len(set(labels[:20])) == 1 and len(set(labels[20:])) == 1 and labels[0] != labels[-1]
    assert sorted(surface_patch_labels(AXES[:3], 64).tolist()) == [0, 1, 2]  # fewer samples than patches: one patch each
    assert np.array_equal(surface_patch_labels(AXES, 6), surface_patch_labels(AXES, 6))  # deterministic


def test_coverage_of_a_known_case():
    labels = surface_patch_labels(AXES, 6)
    # grasp 0: one candidate 1 mm off +x (touches), one 1 cm off +y (too far); grasp 1: a candidate on -x, one on +x
    points = np.array([[[1.001, 0, 0], [0, 1.01, 0]], [[-1.0, 0, 0], [1.0, 0, 0]]])
    distance_m = np.array([[0.001, 0.01], [0.0, -0.004]])  # a candidate pressed 4 mm in still touches
    touched = touched_patches(points, distance_m, AXES, labels, contact_m=0.005)
    assert touched.shape == (2, 6) and touched.sum(axis=1).tolist() == [1, 2]
    assert touched[0, labels[0]] and touched[1, labels[0]] and touched[1, labels[1]]
    assert surface_coverage(touched[:1]) == pytest.approx(1 / 6)
    assert surface_coverage(touched) == pytest.approx(2 / 6)  # +x counted once
    assert surface_coverage(np.zeros((0, 6), bool)) == 0.0
    # NaN distances (unusable grasps) touch nothing
    assert not touched_patches(points, np.full((2, 2), np.nan), AXES, labels).any()


def test_coverage_settings_are_checked():
    with pytest.raises(ValueError, match="coverage_patches"):
        DiversityConfig(coverage_patches=0)
    with pytest.raises(ValueError, match="coverage_contact_m"):
        DiversityConfig(coverage_contact_m=0.0)
