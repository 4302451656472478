"""Each hand description's kinematics and collision shapes against MuJoCo on the same MJCF file.

For the Shadow Hand, Allegro, LEAP and the tests' three-finger hand: over random joint vectors
within the limits, every body's world pose from the pytorch-kinematics chain (``hand.chain``)
matches MuJoCo's ``mj_kinematics`` within 1e-5 m and 1e-4 rad, and every collision shape placed
by those link frames lands on MuJoCo's geom pose. The shapes are the MJCF's collision geoms:
their count, kinds and sizes, checked against numbers read off the shipped files by hand.
"""

from __future__ import annotations

import collections

import numpy as np
import pytest
import torch
from three_finger import write_three_finger

from dexlite_pipeline.hand.derive import quat_to_matrix
from dexlite_pipeline.hand.description import hand_description

POSITION_TOL_M = 1e-5
ROTATION_TOL_RAD = 1e-4


@pytest.fixture(scope="module", params=["shadow", "allegro", "leap", "three_finger"])
def description(request, tmp_path_factory):
    if request.param == "three_finger":
        return hand_description(write_three_finger(tmp_path_factory.mktemp("hand")))
    return hand_description(request.param)


def rotation_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (rad) of the rotation between matrices a and b (..., 3, 3), accurate for small angles."""
    diff = np.swapaxes(a, -1, -2) @ b
    skew = np.stack([diff[..., 2, 1] - diff[..., 1, 2], diff[..., 0, 2] - diff[..., 2, 0], diff[..., 1, 0] - diff[..., 0, 1]], axis=-1)
    return np.arctan2(np.linalg.norm(skew, axis=-1) / 2, (np.trace(diff, axis1=-2, axis2=-1) - 1) / 2)


def fk_errors(description, count: int = 32, seed: int = 0, mujoco_offset=None) -> tuple[float, float, float]:
    """Largest body position (m) and rotation (rad) error, and the largest geom position error (m), chain vs MuJoCo.

    mujoco_offset: added to MuJoCo's joint vector only (rad), to show that the comparison can fail.
    """
    import mujoco

    model = description.mj_model()
    data = mujoco.MjData(model)
    chain = description.chain(dtype=torch.float64)
    limits = description.joint_limits
    q = np.random.default_rng(seed).uniform(limits[:, 0], limits[:, 1], size=(count, len(limits)))
    names = chain.get_joint_parameter_names()
    columns = [description.joint_names.index(n) for n in names]
    frames = chain.forward_kinematics(torch.as_tensor(q[:, columns]))
    position = rotation = geom = 0.0
    for k in range(count):
        data.qpos[model.jnt_qposadr] = q[k] + (0.0 if mujoco_offset is None else mujoco_offset)
        mujoco.mj_kinematics(model, data)
        for b, link in enumerate(description.links):
            matrix = frames[link].get_matrix()[k].numpy()
            position = max(position, float(np.linalg.norm(matrix[:3, 3] - data.xpos[b + 1])))
            rotation = max(rotation, float(rotation_angle(matrix[:3, :3], data.xmat[b + 1].reshape(3, 3))))
        for shape in description.shapes:
            matrix = frames[shape.link].get_matrix()[k].numpy()
            centre = matrix[:3, :3] @ np.asarray(shape.pos) + matrix[:3, 3]
            g = shape.geom
            geom = max(geom, float(np.linalg.norm(centre - data.geom_xpos[g])))
            rotation = max(rotation, float(rotation_angle(matrix[:3, :3] @ quat_to_matrix(shape.quat), data.geom_xmat[g].reshape(3, 3))))
    return position, rotation, geom


def test_every_body_pose_matches_mujoco(description):
    position, rotation, geom = fk_errors(description)
    assert position < POSITION_TOL_M and rotation < ROTATION_TOL_RAD and geom < POSITION_TOL_M, (position, rotation, geom)


def test_the_comparison_can_fail(description):
    """MuJoCo given the last joint 0.01 rad off: the comparison sees it (it compares frames that move)."""
    offset = np.zeros(len(description.joints))
    offset[-1] = 0.01
    position, rotation, _ = fk_errors(description, count=2, mujoco_offset=offset)
    assert rotation > 5e-3


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
