"""The energy's hand geometry helpers: GEMM link maps agree with the hand model; the sphere model covers the shapes."""

from __future__ import annotations

import torch

from dexlite_pipeline.energy.link_map import LinkFrameMap
from dexlite_pipeline.energy.spheres import build_hand_spheres


def test_link_maps_match_the_hand_model(hand):
    pose = torch.rand(5, 28, generator=torch.Generator().manual_seed(0)) - 0.5
    frames = hand.forward(pose)
    link_count = len(hand.link_names)
    points = LinkFrameMap.for_points(hand.contact_points_local, hand.contact_link, link_count)(frames)
    assert torch.allclose(points, hand.contact_candidates(frames), atol=1e-6)
    shape_map = LinkFrameMap.for_frames(hand.shape_rot, hand.shape_pos, hand.shape_link, link_count)
    shape_frames = shape_map(frames)
    rotation, centre = hand.shape_frames(frames)
    assert torch.allclose(shape_frames[..., :3], rotation, atol=1e-6)
    assert torch.allclose(shape_frames[..., 3], centre, atol=1e-6)


def test_link_map_rows_and_transposed_layout_equal_the_dense_map(hand):
    pose = torch.rand(6, 28, generator=torch.Generator().manual_seed(1)) - 0.5
    frames = hand.forward(pose)
    link_count = len(hand.link_names)
    grasp, row = torch.tensor([0, 5, 2, 2]), torch.tensor([3, 0, 17, 139])
    point_map = LinkFrameMap.for_points(hand.contact_points_local, hand.contact_link, link_count)
    dense = point_map(frames)
    assert torch.allclose(point_map.rows(frames, grasp, row), dense[grasp, row], atol=1e-6)
    assert torch.allclose(point_map.transposed(frames), dense.permute(1, 2, 0), atol=1e-6)
    shape_map = LinkFrameMap.for_frames(hand.shape_rot, hand.shape_pos, hand.shape_link, link_count)
    shape = torch.tensor([0, 1, 11, 17])
    assert torch.allclose(shape_map.rows(frames, grasp, shape), shape_map(frames)[grasp, shape], atol=1e-6)


def test_spheres_lie_in_their_shapes_and_cover_them(hand):
    spheres = build_hand_spheres(hand)
    frames = hand.forward(torch.zeros(1, 28))
    centre = LinkFrameMap.for_points(spheres.centre_local, spheres.link, len(hand.link_names))(frames)
    # Every sphere lies within its shape: centre at least a radius deep.
    depth = hand.collision_signed_distance(frames, centre, None)
    assert (depth[0] >= spheres.radius - 1e-5).all()
    # Every surface point of the hand is within (radius + its shape's gap) of a sphere of its link.
    surface = hand.surface_points(frames)[0]
    reach = (torch.cdist(surface, centre[0]) - spheres.radius - spheres.shape_gap[spheres.shape]).where(
        hand.surface_link[:, None] == spheres.link[None, :], torch.tensor(float("inf"))
    )
    assert (reach.min(dim=1).values <= 1e-5).all()
    # Capsule gaps are small (spacing r/2): below half a millimetre.
    capsule = hand.shape_kind == 0
    assert (spheres.shape_gap[capsule] < 5e-4).all()
