"""Hand kinematics against MuJoCo's own forward kinematics, and the point sets."""

import mujoco
import numpy as np
import pytest
import torch
from hand_poses import random_poses

from dexlite_pipeline.hand import JOINT_NAMES
from dexlite_pipeline.hand.mjcf import hand_mjcf_string
from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix


def test_joint_order_and_limits(hand):
    assert hand.joint_names == JOINT_NAMES
    assert len(JOINT_NAMES) == 22
    limits = dict(zip(JOINT_NAMES, hand.joint_limits.tolist()))
    assert limits["robot0:FFJ3"] == pytest.approx([-0.349, 0.349])
    assert limits["robot0:LFJ4"] == pytest.approx([0.0, 0.785])
    assert limits["robot0:THJ4"] == pytest.approx([-1.047, 1.047])
    assert limits["robot0:THJ0"] == pytest.approx([-1.571, 0.0])


def test_forward_kinematics_matches_mujoco(hand):
    model = mujoco.MjModel.from_xml_string(hand_mjcf_string(free_root=True))
    data = mujoco.MjData(model)
    poses = random_poses(hand, 32, seed=1)
    frames = hand.forward(torch.tensor(poses, dtype=torch.float32))
    rot = euler_xyz_to_matrix(torch.tensor(poses[:, 3:6])).numpy()
    for i, pose in enumerate(poses):
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rot[i].reshape(-1))
        data.qpos[:3] = pose[:3]
        data.qpos[3:7] = quat
        data.qpos[7:] = pose[6:]
        mujoco.mj_kinematics(model, data)
        body_names = [model.body(b).name for b in range(1, model.nbody)]
        assert tuple(body_names) == hand.link_names
        np.testing.assert_allclose(frames.translation[i].numpy(), data.xpos[1:], atol=1e-5)
        np.testing.assert_allclose(frames.rotation[i].numpy(), data.xmat[1:].reshape(-1, 3, 3), atol=1e-5)


def test_link_poses_dict_and_gradients(hand):
    pose = torch.tensor(random_poses(hand, 4, seed=2), dtype=torch.float32, requires_grad=True)
    poses = hand.link_poses(pose)
    assert set(poses) == set(hand.link_names)
    assert poses["robot0:ffdistal"].shape == (4, 4, 4)
    poses["robot0:thdistal"][:, :3, 3].sum().backward()
    assert pose.grad is not None and pose.grad[:, 6:].abs().sum() > 0


def test_point_sets_sizes(hand):
    frames = hand.forward(torch.zeros(2, 28))
    assert hand.contact_candidates(frames).shape == (2, 140, 3)
    assert hand.penetration_keypoints(frames).shape[-1] == 3
    assert hand.surface_points(frames).shape[1] > 500


def test_contact_candidates_lie_on_palmar_side(hand):
    # Open flat hand at the origin: finger pads face -y, so every finger candidate has y < 0.
    frames = hand.forward(torch.zeros(1, 28))
    points = hand.contact_candidates(frames)[0]
    finger = hand.contact_link < hand.link_index["robot0:thbase"]
    assert (points[finger, 1] < 0).all()


def test_collision_signed_distance(hand):
    frames = hand.forward(torch.zeros(1, 28))
    # Centre of the ffproximal capsule axis is inside by its radius (1 cm).
    centre = frames.translation[0, hand.link_index["robot0:ffproximal"]] + torch.tensor([0.0, 0.0, 0.0225])
    far = torch.tensor([0.0, -0.5, 0.0])
    sd = hand.collision_signed_distance(frames, torch.stack([centre, far])[None])
    assert sd[0, 0].item() == pytest.approx(0.01, abs=1e-6)
    assert sd[0, 1].item() < -0.4
    # Hand surface samples lie on their own shape and so on or inside the union (sd >= 0 up to float error).
    surface = hand.surface_points(frames)
    assert (hand.collision_signed_distance(frames, surface) > -1e-6).all()


def test_side_candidates_face_the_thumb_from_the_index_middle_phalanx(hand):
    """The lateral grasp's candidates: on the surface of the index finger's middle capsule, on its radial side (the
    link's +x, toward the thumb), after the 140 pads in the contact table."""
    assert hand.pad_candidate_count == 140 and len(hand.side_contact_link) == 10
    assert torch.equal(hand.all_contact_link[:140], hand.contact_link)
    link = hand.link_index["robot0:ffmiddle"]
    assert set(hand.side_contact_link.tolist()) == {link}
    capsule = hand._capsule_of_link("robot0:ffmiddle")
    local = hand.side_contact_points_local - hand.shape_pos[capsule]
    radius, half = hand.shape_size[capsule, :2]
    assert torch.allclose(local[:, :2].norm(dim=1), radius.expand(10), atol=1e-6) and bool((local[:, 2].abs() < half).all())
    assert bool((local[:, 0] / radius > 0.8).all())  # radial side: toward +x, within 37° of it
    assert hand.candidates_on(("robot0:ffmiddle",)) == tuple(range(10, 20)) + tuple(range(140, 150))
    thumb_base = hand.forward(torch.zeros(1, 28)).translation[0, hand.link_index["robot0:thbase"]]
    assert float(thumb_base[0]) > 0  # the thumb is on the +x side of the palm


def test_thumb_tip_candidates_cover_the_distal_capsule_out_to_its_tip(hand):
    """The thumb-tip candidates (pinch and tripod): appended after the pads and side candidates (indices 150–159, so no
    earlier index moves), on the surface of the thumb's distal capsule, on its palmar side (−x, as its pads), beyond the
    pads' last row and within 3 mm of the tip of the capsule."""
    link = hand.link_index["robot0:thdistal"]
    assert len(hand.all_contact_link) == 160 and set(hand.tip_contact_link.tolist()) == {link}
    assert hand.candidates_on(("robot0:thdistal",), "tip") == tuple(range(150, 160))
    assert hand.candidates_on(("robot0:thdistal",), "pad") == tuple(range(130, 140))
    assert torch.equal(hand.all_contact_link[:150], torch.cat([hand.contact_link, hand.side_contact_link]))
    assert hand.contact_kinds[149:151] == ("side", "tip")
    capsule = hand._capsule_of_link("robot0:thdistal")
    radius, half = hand.shape_size[capsule, :2].double()
    local = hand.tip_contact_points_local.double() - hand.shape_pos[capsule].double()  # capsule frame (axis +z)
    axis_point = torch.stack([torch.zeros(10), torch.zeros(10), local[:, 2].clamp(-half, half)], dim=1).double()
    assert torch.allclose((local - axis_point).norm(dim=1), radius.expand(10), atol=1e-6)  # on the surface
    assert bool((local[:, 0] < 0).all()) and bool((local[:, 0] / local[:, :2].norm(dim=1) < -0.9).all())  # palmar: within 25° of −x
    pad_reach = float(hand.contact_points_local[130:140, 2].max() - hand.shape_pos[capsule, 2])
    assert float(local[:, 2].min()) > pad_reach + 0.003  # beyond the pads (their last row is 8.3 mm out)
    tip = torch.tensor([0.0, 0.0, float(half + radius)], dtype=torch.float64)
    assert float((local - tip).norm(dim=1).min()) < 0.003 and float(local[:, 2].max()) > float(half + radius) - 0.001
