"""Initial hand poses for optimization from scratch (DexGraspNet's convex-hull start).

For each grasp: a point q on the object's convex hull (area-weighted), its outward
normal n; the approach direction a = −n tilted by up to ``jitter_deg`` about a random
axis; the palm placed ``distance_m`` (uniform in the range) back from q along a, facing
the object (its palmar normal, tilted toward the fingers as DexGraspNet does, along a),
with a uniformly random roll about a; the joints drawn around a mean open pose with
σ = ``joint_sigma_fraction`` of each joint's range, clipped to the limits.

On a table (tabletop mode) a start whose palm origin would lie below the support plane is
drawn again (hull point, tilt and distance), so every palm starts above the table; floating
starts draw exactly what they drew before tabletop mode existed.
"""

from __future__ import annotations

import math
import numpy as np
import torch

from dexlite_pipeline.hand.model import JOINT_NAMES, ShadowHand
from dexlite_pipeline.hand.rotation import matrix_to_euler_xyz
from dexlite_pipeline.objects.assets import ObjectAsset
from dexlite_pipeline.optim.config import InitConfig

# A relaxed, open hand: slight spread, middle joints a little bent, thumb opposed.
MEAN_OPEN_POSE = {
    "FFJ3": 0.1, "FFJ1": 0.6, "MFJ1": 0.6, "RFJ3": -0.1, "RFJ1": 0.6,
    "LFJ3": -0.2, "LFJ1": 0.6, "THJ3": 1.2, "THJ1": -0.2,
}
# Approach direction in the palm frame: the palmar normal (−y) tilted 30° toward the fingers (+z).
PALM_APPROACH = (0.0, -math.cos(math.radians(30.0)), math.sin(math.radians(30.0)))


def mean_open_joints(hand: ShadowHand) -> torch.Tensor:
    """(22,) the mean open pose, in joint order."""
    values = [MEAN_OPEN_POSE.get(name.removeprefix("robot0:"), 0.0) for name in JOINT_NAMES]
    return torch.tensor(values, dtype=hand.dtype)


class HullSampler:
    """Area-weighted points and outward normals on each object's convex hull (normalized frame)."""

    def __init__(self, assets: list[ObjectAsset]) -> None:
        self.triangles, self.normals, self.areas = [], [], []
        for asset in assets:
            hull = asset.load_mesh().convex_hull
            self.triangles.append(torch.tensor(np.asarray(hull.triangles), dtype=torch.float64))
            self.normals.append(torch.tensor(np.asarray(hull.face_normals), dtype=torch.float64))
            self.areas.append(torch.tensor(np.asarray(hull.area_faces), dtype=torch.float64))

    def sample(self, object_index: torch.Tensor, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        """Points (B, 3) and outward normals (B, 3) in each object's normalized frame."""
        batch = object_index.shape[0]
        points = torch.zeros(batch, 3, dtype=torch.float64)
        normals = torch.zeros(batch, 3, dtype=torch.float64)
        index = object_index.cpu()
        for obj in torch.unique(index).tolist():
            rows = (index == obj).nonzero(as_tuple=True)[0]
            face = torch.multinomial(self.areas[obj], len(rows), replacement=True, generator=generator)
            u, v = torch.rand(2, len(rows), 1, generator=generator, dtype=torch.float64)
            flip = (u + v) > 1
            u, v = torch.where(flip, 1 - u, u), torch.where(flip, 1 - v, v)
            tri = self.triangles[obj][face]
            points[rows] = tri[:, 0] + u * (tri[:, 1] - tri[:, 0]) + v * (tri[:, 2] - tri[:, 0])
            normals[rows] = self.normals[obj][face]
        return points, normals


def _unit(v: torch.Tensor) -> torch.Tensor:
    return v / v.norm(dim=-1, keepdim=True).clamp(min=1e-12)


def _random_perpendicular(direction: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """Unit vectors (B, 3) perpendicular to ``direction``, uniformly distributed around it."""
    while True:
        r = torch.randn(direction.shape, generator=generator, dtype=direction.dtype)
        perp = r - (r * direction).sum(-1, keepdim=True) * direction
        if bool((perp.norm(dim=-1) > 1e-6).all()):
            return _unit(perp)


# Redraws of starts whose palm lies below the table before giving up on a grasp's start (tabletop mode).
MAX_TABLE_REDRAWS = 100


class NoStartAboveTable(ValueError):
    """An object whose convex-hull starts all put the palm below its table."""


def _palm_origins(hulls: HullSampler, object_index, scale, config: InitConfig, generator) -> tuple[torch.Tensor, torch.Tensor]:
    """Palm origins (B, 3) and approach directions (B, 3): a hull point, a tilted inward approach, a distance back."""
    batch = object_index.shape[0]
    point, normal = hulls.sample(object_index, generator)
    point = point * scale.cpu().double()[:, None]
    inward = -normal
    tilt = torch.rand(batch, 1, generator=generator, dtype=torch.float64) * math.radians(config.jitter_deg)
    approach = _unit(torch.cos(tilt) * inward + torch.sin(tilt) * _random_perpendicular(inward, generator))
    low, high = config.distance_m
    distance = low + (high - low) * torch.rand(batch, 1, generator=generator, dtype=torch.float64)
    return point - distance * approach, approach


def initial_poses(
    hand: ShadowHand,
    hulls: HullSampler,
    object_index: torch.Tensor,
    scale: torch.Tensor,
    config: InitConfig,
    generator: torch.Generator,
    support: tuple[torch.Tensor, torch.Tensor] | None = None,
) -> torch.Tensor:
    """(B, 28) stored hand poses facing each grasp's object from outside its convex hull.

    ``support`` (tabletop mode): per grasp the table's normal (B, 3) and offset in metres (B,);
    starts with the palm origin below the table are redrawn (``NoStartAboveTable`` if some
    stay below after ``MAX_TABLE_REDRAWS`` rounds).
    """
    batch = object_index.shape[0]
    palm_origin, approach = _palm_origins(hulls, object_index, scale, config, generator)
    if support is not None:
        normal, offset = (t.detach().cpu().double() for t in support)
        for _ in range(MAX_TABLE_REDRAWS):
            below = ((palm_origin * normal).sum(-1) + offset < 0).nonzero(as_tuple=True)[0]
            if len(below) == 0:
                break
            palm_origin[below], approach[below] = _palm_origins(hulls, object_index.cpu()[below], scale.cpu()[below], config, generator)
        else:
            raise NoStartAboveTable(f"no start above the table after {MAX_TABLE_REDRAWS} redraws for {len(below)} grasps")

    # Rotation taking the palm-frame approach to ``approach``, with a random roll about it.
    hand_a = torch.tensor(PALM_APPROACH, dtype=torch.float64)
    hand_b = torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64)
    hand_frame = torch.stack([hand_a, hand_b, torch.linalg.cross(hand_a, hand_b)], dim=1)  # columns
    world_b = _random_perpendicular(approach, generator)
    world_frame = torch.stack([approach, world_b, torch.linalg.cross(approach, world_b)], dim=2)
    rotation = world_frame @ hand_frame.T

    limits = hand.joint_limits.cpu().double()
    sigma = config.joint_sigma_fraction * (limits[:, 1] - limits[:, 0])
    joints = mean_open_joints(hand).double() + sigma * torch.randn(batch, len(JOINT_NAMES), generator=generator, dtype=torch.float64)
    joints = torch.maximum(torch.minimum(joints, limits[:, 1]), limits[:, 0])
    pose = torch.cat([palm_origin, matrix_to_euler_xyz(rotation), joints], dim=1)
    return pose.to(hand.device, hand.dtype)
