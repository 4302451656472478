"""Start poses of the precision grasp types (``optim.grasp_types``: pinch, tripod, lateral).

A type's grasp centre c (midway between its two opposing sides' pads in the aperture pose, palm frame), its opening
axis u (from the thumb side to the finger side) and its approach axis a (c's direction from the palm origin, made
perpendicular to u: the object enters the opening from the side away from the palm) are read off the hand's
kinematics. For each start a target point p, an approach direction A and an opening direction U ⟂ A are drawn in the
object frame:

- from the side: p a point of the convex hull (area-weighted, ``optim.init.HullSampler``), A its inward normal, U
  uniformly around A;
- from above (palm facing down): p a point of the object's rim, the hull edges where its upward-facing top (faces
  within ``TOP_FACE_DEG`` of the table's upward normal) meets the rest, sampled by length; A the downward normal, U
  horizontal across the rim (outward or inward at random), so the opposing pads straddle it.

A is then tilted by up to the type's ``jitter_deg`` about a random axis (U made perpendicular again), the palm
rotated so that a → A and u → U, and placed so that c lies ``centre_distance_m`` (uniform in the type's range) back
from p along A. The joints are the aperture plus noise of σ = ``joint_sigma_fraction`` of each range, clipped to the
limits. On a table a start whose palm origin or grasp centre would lie below it is drawn again (target, directions
and distance), as power starts are.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from dexlite_pipeline.hand.model import JOINT_NAMES, ShadowHand
from dexlite_pipeline.hand.rotation import matrix_to_euler_xyz
from dexlite_pipeline.objects.assets import ObjectAsset
from dexlite_pipeline.optim.grasp_types import GraspType, candidate_group
from dexlite_pipeline.optim.init import MAX_TABLE_REDRAWS, HullSampler, NoStartAboveTable

# A hull face whose outward normal is within this angle of the table's upward normal belongs to the object's top.
TOP_FACE_DEG = 30.0
# The upward normal of a floating object (no table): the object frame's +z, against gravity.
FLOATING_UP = (0.0, 0.0, 1.0)


def _unit(v: torch.Tensor) -> torch.Tensor:
    return v / v.norm(dim=-1, keepdim=True).clamp(min=1e-12)


def _perpendicular_part(v: torch.Tensor, axis: torch.Tensor) -> torch.Tensor:
    """The part of ``v`` (B, 3) perpendicular to unit ``axis`` (B, 3)."""
    return v - (v * axis).sum(-1, keepdim=True) * axis


def _random_perpendicular(direction: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """Unit vectors (B, 3) perpendicular to unit ``direction`` (B, 3), uniformly around it."""
    while True:
        perp = _perpendicular_part(torch.randn(direction.shape, generator=generator, dtype=direction.dtype), direction)
        if bool((perp.norm(dim=-1) > 1e-6).all()):
            return _unit(perp)


class TypeGeometry:
    """A grasp type's grasp centre, opening axis and approach axis in the palm frame (module docstring), float64."""

    def __init__(self, hand: ShadowHand, grasp_type: GraspType) -> None:
        if grasp_type.opposition is None:
            raise ValueError(f"grasp type {grasp_type.name} has no opposing sides (its starts are the convex-hull starts)")
        pose = torch.zeros(1, 28, dtype=hand.dtype, device=hand.device)
        pose[0, 6:] = grasp_type.aperture_joints().to(hand.dtype)
        frames = hand.forward(pose)
        table = frames.transform(hand.all_contact_points_local, hand.all_contact_link)[0].double().cpu()
        sides = [table[[i for group in side for i in candidate_group(hand, group)]].mean(0) for side in grasp_type.opposition]
        self.centre = (sides[0] + sides[1]) / 2
        self.opening = _unit(sides[1] - sides[0])
        self.approach = _unit(_perpendicular_part(self.centre[None], self.opening[None])[0])


class RimSampler:
    """Per object, the rim of its convex hull's top (module docstring): edge segments and the horizontal direction
    across each (normalized frame), for the object's upward normal."""

    def __init__(self, assets: list[ObjectAsset], up: list[tuple[float, float, float]]) -> None:
        self.hulls = [asset.load_mesh().convex_hull for asset in assets]
        self.up = [np.asarray(u, dtype=np.float64) / np.linalg.norm(u) for u in up]
        self._rims: dict[int, tuple[torch.Tensor, torch.Tensor, torch.Tensor]] = {}
        self.height = [float((hull.vertices @ u).max() - (hull.vertices @ u).min()) for hull, u in zip(self.hulls, self.up)]

    def rim(self, obj: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Object ``obj``'s rim: segment ends (E, 2, 3), lengths (E,), across directions (E, 3) (horizontal, pointing
        out of the top). Empty when its hull has no top face."""
        if obj not in self._rims:
            hull, up = self.hulls[obj], self.up[obj]
            top = hull.face_normals @ up >= math.cos(math.radians(TOP_FACE_DEG))
            pairs, edges = hull.face_adjacency, hull.face_adjacency_edges
            on_rim = top[pairs[:, 0]] != top[pairs[:, 1]]
            ends = hull.vertices[edges[on_rim]]  # (E, 2, 3)
            tangent = ends[:, 1] - ends[:, 0]
            length = np.linalg.norm(tangent, axis=1)
            across = np.cross(up, tangent)
            across /= np.maximum(np.linalg.norm(across, axis=1, keepdims=True), 1e-12)
            side_face = np.where(top[pairs[on_rim, 0]], pairs[on_rim, 1], pairs[on_rim, 0])
            across *= np.where((across * hull.face_normals[side_face]).sum(1) < 0, -1.0, 1.0)[:, None]
            self._rims[obj] = tuple(torch.as_tensor(a, dtype=torch.float64) for a in (ends, length, across))
        return self._rims[obj]

    def sample(self, obj: int, count: int, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor] | None:
        """``count`` rim points (normalized frame) and the across directions there; None when the object has no rim."""
        ends, length, across = self.rim(obj)
        if not len(length) or float(length.sum()) <= 0:
            return None
        edge = torch.multinomial(length, count, replacement=True, generator=generator)
        t = torch.rand(count, 1, generator=generator, dtype=torch.float64)
        return ends[edge, 0] + t * (ends[edge, 1] - ends[edge, 0]), across[edge]


def _tilted(direction: torch.Tensor, jitter_deg: float, generator: torch.Generator) -> torch.Tensor:
    """``direction`` (B, 3) tilted by an angle uniform in [0, ``jitter_deg``] about a random perpendicular axis."""
    tilt = torch.rand(direction.shape[0], 1, generator=generator, dtype=torch.float64) * math.radians(jitter_deg)
    return _unit(torch.cos(tilt) * direction + torch.sin(tilt) * _random_perpendicular(direction, generator))


def _targets(grasp_type: GraspType, hulls: HullSampler, rims: RimSampler, obj: int, scale: torch.Tensor,
             table_height_m: float | None, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Target points (B, 3, metres), approach directions A (B, 3) and opening directions U (B, 3) for one object."""
    count = scale.shape[0]
    up = torch.as_tensor(rims.up[obj], dtype=torch.float64).expand(count, 3)
    point, normal = hulls.sample(torch.full((count,), obj, dtype=torch.long), generator)
    approach = -normal
    opening = _random_perpendicular(approach, generator)
    low = table_height_m is not None and table_height_m < grasp_type.low_object_height_m
    above = torch.ones(count, dtype=torch.bool) if low else torch.rand(count, generator=generator, dtype=torch.float64) < grasp_type.above_share
    rim = rims.sample(obj, count, generator)
    if rim is not None and bool(above.any()):
        rim_point, across = rim
        sign = torch.where(torch.rand(count, 1, generator=generator, dtype=torch.float64) < 0.5, -1.0, 1.0)
        point = torch.where(above[:, None], rim_point, point)
        approach = torch.where(above[:, None], -up, approach)
        opening = torch.where(above[:, None], sign * across, opening)
    approach = _tilted(approach, grasp_type.jitter_deg, generator)
    opening = _unit(_perpendicular_part(opening, approach))
    return point * scale[:, None], approach, opening


def type_start_poses(
    hand: ShadowHand,
    grasp_type: GraspType,
    geometry: TypeGeometry,
    hulls: HullSampler,
    rims: RimSampler,
    object_index: torch.Tensor,
    scale: torch.Tensor,
    joint_sigma_fraction: float,
    generator: torch.Generator,
    support: tuple[torch.Tensor, torch.Tensor] | None = None,
) -> torch.Tensor:
    """(B, 28) stored start poses of ``grasp_type`` (module docstring), object by object in order of first appearance.

    ``support`` (tabletop mode): per grasp the table's normal (B, 3) and offset in metres (B,): starts with the palm
    origin or the grasp centre below the table are drawn again (``NoStartAboveTable`` after ``MAX_TABLE_REDRAWS``
    rounds); the object's height on its table decides whether it is approached from above only.
    """
    index = object_index.cpu()
    scale = scale.detach().cpu().double()
    normal, offset = (None, None) if support is None else (t.detach().cpu().double() for t in support)
    batch = len(index)
    centre_target, approach, opening = (torch.zeros(batch, 3, dtype=torch.float64) for _ in range(3))
    distance = torch.zeros(batch, 1, dtype=torch.float64)
    hand_frame = torch.stack([geometry.approach, geometry.opening, torch.linalg.cross(geometry.approach, geometry.opening)], dim=1)
    low, high = grasp_type.centre_distance_m
    for obj in dict.fromkeys(index.tolist()):
        rows = (index == obj).nonzero(as_tuple=True)[0]
        height = None if support is None else rims.height[obj] * float(scale[rows].max())
        pending = torch.arange(len(rows))
        for _ in range(MAX_TABLE_REDRAWS):
            r = rows[pending]
            point, a, u = _targets(grasp_type, hulls, rims, obj, scale[r], height, generator)
            d = low + (high - low) * torch.rand(len(r), 1, generator=generator, dtype=torch.float64)
            centre_target[r], approach[r], opening[r], distance[r] = point, a, u, d
            if support is None:
                break
            centre = point - d * a
            world_frame = torch.stack([a, u, torch.linalg.cross(a, u)], dim=2)
            palm = centre - (world_frame @ hand_frame.T @ geometry.centre)
            height_of = lambda x, r=r: (x * normal[r]).sum(-1) + offset[r]  # noqa: E731
            pending = pending[(height_of(palm) < 0) | (height_of(centre) < 0)]
            if not len(pending):
                break
        else:
            raise NoStartAboveTable(f"no start above the table after {MAX_TABLE_REDRAWS} redraws for {len(pending)} grasps")
    world_frame = torch.stack([approach, opening, torch.linalg.cross(approach, opening)], dim=2)
    rotation = world_frame @ hand_frame.T
    palm_origin = centre_target - distance * approach - rotation @ geometry.centre
    limits = hand.joint_limits.cpu().double()
    sigma = joint_sigma_fraction * (limits[:, 1] - limits[:, 0])
    joints = grasp_type.aperture_joints() + sigma * torch.randn(batch, len(JOINT_NAMES), generator=generator, dtype=torch.float64)
    joints = torch.maximum(torch.minimum(joints, limits[:, 1]), limits[:, 0])
    pose = torch.cat([palm_origin, matrix_to_euler_xyz(rotation), joints], dim=1)
    return pose.to(hand.device, hand.dtype)
