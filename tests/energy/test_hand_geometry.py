"""The energy's hand geometry helpers: GEMM link maps agree with the hand model; the sphere model covers the shapes."""

from __future__ import annotations

import math

import torch

from dexlite_pipeline.energy.link_map import LinkFrameMap
from dexlite_pipeline.energy.spheres import build_hand_spheres
from dexlite_pipeline.hand.model import CAPSULE


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
    # Every point of every shape's surface, densely sampled with its edges and corners, is
    # within (radius + the shape's gap) of one of its spheres; boxes reach the gap at their corners.
    rotation, position = hand.shape_frames(frames)
    for s in range(len(hand.shape_kind)):
        local = _dense_surface(int(hand.shape_kind[s]), hand.shape_size[s].double())
        points = local @ rotation[0, s].double().T + position[0, s].double()
        mine = spheres.shape == s
        reach = (torch.cdist(points, centre[0, mine].double()) - spheres.radius[mine].double()).min(dim=1).values
        assert float(reach.max()) <= float(spheres.shape_gap[s]) + 1e-6, f"shape {s}"
        if int(hand.shape_kind[s]) != CAPSULE:
            assert float(reach.max()) >= float(spheres.shape_gap[s]) - 1e-6, f"box {s}: the gap is tight"
    # Capsule gaps are small (spacing r/2): below half a millimetre.
    capsule = hand.shape_kind == CAPSULE
    assert (spheres.shape_gap[capsule] < 5e-4).all()


def _dense_surface(kind: int, size: torch.Tensor, n: int = 41) -> torch.Tensor:
    """Points on a capsule (axis z) or box surface in its frame: grids that include every edge and corner."""
    grid = torch.linspace(-1.0, 1.0, n, dtype=torch.float64)
    u, v = torch.meshgrid(grid, grid, indexing="ij")
    u, v = u.reshape(-1), v.reshape(-1)
    if kind == CAPSULE:
        radius, half = float(size[0]), float(size[1])
        angle = math.pi * u
        cylinder = torch.stack([radius * angle.cos(), radius * angle.sin(), half * v], dim=1)
        polar = math.pi / 2 * (v + 1) / 2  # 0 (pole) .. pi/2 (equator)
        cap = torch.stack([radius * polar.sin() * angle.cos(), radius * polar.sin() * angle.sin(), radius * polar.cos()], dim=1)
        return torch.cat([cylinder, cap + torch.tensor([0, 0, half]), cap * torch.tensor([1, 1, -1]) - torch.tensor([0, 0, half])])
    half = size[:3]
    faces = []
    for axis in range(3):
        a, b = [k for k in range(3) if k != axis]
        for sign in (-1.0, 1.0):
            face = torch.zeros(len(u), 3, dtype=torch.float64)
            face[:, axis], face[:, a], face[:, b] = sign * half[axis], u * half[a], v * half[b]
            faces.append(face)
    return torch.cat(faces)
