"""Each hand description's kinematics and collision shapes against MuJoCo on the same MJCF file.

For the Shadow Hand, Allegro, LEAP and the tests' three-finger hand: over random joint vectors
within the limits, every body's world pose from the pytorch-kinematics chain (``hand.chain``)
matches MuJoCo's ``mj_kinematics`` within 1e-5 m and 1e-4 rad, and every collision shape placed
by those link frames lands on MuJoCo's geom pose (``hand.check.kinematics_errors``, which
``dexlite hand-check`` reports). The shapes are the MJCF's collision geoms:
their count, kinds and sizes, checked against numbers read off the shipped files by hand.
"""

from __future__ import annotations

import collections

import numpy as np
import pytest
from three_finger import write_three_finger

from dexlite_pipeline.hand.check import POSITION_TOL_M, ROTATION_TOL_RAD, kinematics_errors, random_joint_vectors
from dexlite_pipeline.hand.derive import quat_to_matrix
from dexlite_pipeline.hand.description import hand_description


@pytest.fixture(scope="module", params=["shadow", "allegro", "leap", "three_finger"])
def description(request, tmp_path_factory):
    if request.param == "three_finger":
        return hand_description(write_three_finger(tmp_path_factory.mktemp("hand")))
    return hand_description(request.param)


def test_every_body_pose_matches_mujoco(description):
    errors = kinematics_errors(description, random_joint_vectors(description, 32, seed=0))
    assert errors.ok and errors.position_m < POSITION_TOL_M and errors.rotation_rad < ROTATION_TOL_RAD and errors.geom_m < POSITION_TOL_M, errors


def test_the_comparison_can_fail(description):
    """MuJoCo given the last joint 0.01 rad off: the comparison sees it (it compares frames that move)."""
    joints = random_joint_vectors(description, 2, seed=1)
    shifted = joints.copy()
    shifted[:, -1] += 0.01
    errors = kinematics_errors(description, joints, mujoco_joints=shifted)
    assert errors.rotation_rad > 5e-3 and not errors.ok


def test_collision_shapes_are_the_mjcf_collision_geoms(description):
    model = description.mj_model()
    colliding = [g for g in range(model.ngeom) if model.geom_contype[g] or model.geom_conaffinity[g]]
    assert sorted([s.geom for s in description.shapes] + [model.geom(n).id for n in description.left_out_geoms]) == colliding
    for shape in description.shapes:
        g = shape.geom
        np.testing.assert_allclose(shape.size, model.geom_size[g])
        assert shape.link == model.body(model.geom_bodyid[g]).name
        assert len(shape.points) >= 4 and np.allclose(np.linalg.norm(shape.normals, axis=1), 1.0)


@pytest.mark.parametrize("name, kinds, sizes", [
    ("shadow", {"capsule": 15, "box": 3}, {"robot0:C_palm0": (0.032, 0.0111, 0.049)}),
    ("allegro", {"box": 17, "capsule": 4}, {"palm": (0.0204, 0.0565, 0.0475)}),
    ("leap", {"box": 67, "mesh": 4}, {"palm_collision_1": (0.011, 0.013, 0.017), "if_px_collision": (0.017, 0.013, 0.011)}),
])  # fmt: skip
def test_shape_counts_kinds_and_sizes_as_written_in_the_files(name, kinds, sizes):
    """Numbers read off the MJCF files by hand (Allegro's boxes come from its <default> classes)."""
    description = hand_description(name)
    assert dict(collections.Counter(s.kind for s in description.shapes)) == kinds
    by_name = {s.name: s for s in description.shapes}
    by_link = {s.link: s for s in description.shapes if s.kind == "box"}  # Allegro's palm box has no name
    for key, size in sizes.items():
        shape = by_name.get(key) or by_link[key]
        np.testing.assert_allclose(shape.size, size, atol=1e-9)
    if name == "allegro":
        tips = [s for s in description.shapes if s.kind == "capsule"]
        assert {s.link for s in tips} == {"ff_tip", "mf_tip", "rf_tip", "th_tip"}
        assert {(round(s.size[0], 6), round(s.size[1], 6)) for s in tips} == {(0.012, 0.01), (0.012, 0.008)}
    if name == "shadow":
        assert description.left_out_geoms == ("robot0:V_thbase", "robot0:V_thhub")


def test_a_mesh_collision_geom_gets_a_tight_box_and_samples_on_it():
    """LEAP's fingertip meshes: the fitted box is MuJoCo's own bounding box of the geom, and the samples lie in it."""
    description = hand_description("leap")
    model = description.mj_model()
    meshes = [s for s in description.shapes if s.kind == "mesh"]
    assert {s.name for s in meshes} == {"if_tip", "mf_tip", "rf_tip", "th_tip"}
    for shape in meshes:
        aabb = model.geom_aabb[model.geom(shape.name).id]
        np.testing.assert_allclose(shape.box_centre, aabb[:3], atol=1e-7)
        np.testing.assert_allclose(shape.box_half, aabb[3:], atol=1e-7)
        local = (shape.points - np.asarray(shape.pos)) @ quat_to_matrix(shape.quat)
        assert np.all(np.abs(local - shape.box_centre) <= np.asarray(shape.box_half) + 1e-7)
        assert len(shape.points) >= 100  # ~2 mm apart on a fingertip of a few square centimetres
