"""A hand from its MJCF as the energies' hand model (``hand.described.DescribedHand``)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from described_hands import three_finger_hand  # noqa: E402

from dexlite_pipeline.hand.described import REST_CLEARANCE_M, DescribedHand  # noqa: E402
from dexlite_pipeline.hand.model import BOX, CAPSULE, ShadowHand, box_signed_distance  # noqa: E402


def test_the_shadow_hand_described_has_the_shadow_hands_link_frames():
    """The same file read two ways: the description's chain and ``ShadowHand``'s give the same frames."""
    shadow, described = ShadowHand(), DescribedHand("shadow")
    assert described.pose_dim == 28 and described.joint_names == shadow.joint_names and described.link_names == shadow.link_names
    pose = torch.randn(6, 28, generator=torch.Generator().manual_seed(0)) * 0.3
    a, b = shadow.forward(pose), described.forward(pose)
    assert torch.allclose(a.rotation, b.rotation, atol=1e-6) and torch.allclose(a.translation, b.translation, atol=1e-6)


def test_the_three_finger_hand_has_its_own_pose_length_and_shapes(tmp_path):
    hand = three_finger_hand(tmp_path)
    assert hand.pose_dim == 15 and len(hand.joint_names) == 9 and hand.joint_limits.shape == (9, 2)
    assert (hand.shape_kind == CAPSULE).sum() == 9 and (hand.shape_kind == BOX).sum() == 1
    assert hand.contact_points_local.shape == (110, 3) and hand.all_contact_points_local.shape == (110, 3)
    frames = hand.forward(torch.zeros(2, 15))
    assert frames.translation.shape == (2, 10, 3)
    assert torch.allclose(frames.translation[:, 0], torch.zeros(3)) and torch.allclose(frames.rotation[:, 0], torch.eye(3))  # the pose is the root frame
    assert hand.finger_joints == ((0, 1, 2), (3, 4, 5), (6, 7, 8))


@pytest.mark.parametrize("name", ["allegro", "leap"])
def test_the_open_hand_does_not_penetrate_itself(name):
    """No keypoint pair counted by E_spen is closer than its margin in the open pre-grasp (LEAP's fingers are built
    1.3 cm apart: such pairs are left out), and links joined rigidly (a fingertip body under its distal link) never pair."""
    from dexlite_pipeline.energy.terms import SelfPenetrationTerm

    hand = DescribedHand(name)
    pose = torch.zeros(1, hand.pose_dim)
    pose[0, 6:] = hand.pregrasp_joints()
    assert float(SelfPenetrationTerm(hand, REST_CLEARANCE_M).evaluate_with_torch(hand.forward(pose))) == 0.0
    group = hand._rigid_group()
    pairs = hand.keypoint_pair_mask.nonzero().tolist()
    assert pairs and all(group[int(hand.keypoint_link[i])] != group[int(hand.keypoint_link[j])] for i, j in pairs)


def test_a_mesh_geom_is_its_fitted_box_and_holds_the_mesh():
    """LEAP's fingertip meshes become boxes: every surface sample of the mesh lies in its box (to 0.01 mm)."""
    hand = DescribedHand("leap")
    shapes = [s for s, shape in enumerate(hand.description.shapes) if shape.kind == "mesh"]
    assert len(shapes) == 4
    for s in shapes:
        assert int(hand.shape_kind[s]) == BOX
        points = torch.as_tensor(hand.description.shapes[s].points, dtype=torch.float32)
        local = (points - hand.shape_pos[s]) @ hand.shape_rot[s]
        assert float(box_signed_distance(local, hand.shape_size[s]).min()) > -1e-5
