"""Initial hand poses for optimization from scratch (DexGraspNet's convex-hull start).

For each grasp: a point q on the object's convex hull (area-weighted), its outward
normal n; the approach direction a = −n tilted by up to ``jitter_deg`` about a random
axis; the palm placed ``distance_m`` (uniform in the range) back from q along a, facing
the object (its palmar normal, tilted toward the fingers as DexGraspNet does, along a),
with a uniformly random roll about a; the joints drawn around a mean open pose with
σ = ``joint_sigma_fraction`` of each joint's range, clipped to the limits.

On a table (tabletop mode) a start whose palm origin would lie below the support plane is
drawn again (hull point, tilt and distance), so every palm starts above the table; floating
starts draw exactly what they drew before tabletop mode existed. With ``start_faces`` "top_and_sides"
half the tabletop starts, at random, take their hull point on the faces facing up (within
``TOP_FACE_DEG`` of the table's normal) and the others on the rest, each by area: drawn by area
alone, a tall object is nearly always approached from the side.

A hand from its MJCF (``hand.described.DescribedHand``) starts the same way from its own description: its palm
frame's origin (the centre of its palm's contact candidates) at the start point, along the approach the direction
near its palm normal along which its thumb's tip and its fingertips lie equally far (``balanced_approach``), its
joints around its open pre-grasp curled a little and its thumb turned to face the fingers (``described_start_poses``,
``opposed_pregrasp``).
"""

from __future__ import annotations

import functools
import math

import numpy as np
import torch

from dexlite_pipeline.hand.described import DescribedHand, is_described
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
PALM_TILT_DEG = 30.0  # the same tilt for a hand from its MJCF without an opposing finger (``balanced_approach``)
# A hand from its MJCF starts with each joint this fraction of the way from its open pre-grasp to the limit it flexes
# toward (the larger-magnitude one; joints with symmetric ranges stay): like the Shadow Hand's mean open pose, a hand
# slightly curled. On Allegro and a can-sized cylinder (32 starts) the open, flat hand held 1, this 3 (docs/hands.md).
START_CURL = 0.3


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

    def sample(self, object_index: torch.Tensor, generator: torch.Generator, up: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """Points (B, 3) and outward normals (B, 3) in each object's normalized frame, each on a face drawn by area.

        ``up`` (B, 3; its table's upward normal per row, the same for one object's rows): half the rows, drawn at
        random, on the object's top (faces whose normal is within ``TOP_FACE_DEG`` of up), the others on the rest, each
        by area within its group (``InitConfig.start_faces`` "top_and_sides"); an object with no top or no other face
        draws all its rows from every face."""
        batch = object_index.shape[0]
        points = torch.zeros(batch, 3, dtype=torch.float64)
        normals = torch.zeros(batch, 3, dtype=torch.float64)
        index = object_index.cpu()
        on_top = None if up is None else torch.rand(batch, generator=generator, dtype=torch.float64) < 0.5
        for obj in torch.unique(index).tolist():
            rows = (index == obj).nonzero(as_tuple=True)[0]
            if on_top is None:
                face = torch.multinomial(self.areas[obj], len(rows), replacement=True, generator=generator)
            else:
                face = self._faces_by_group(obj, on_top[rows], up[rows[0]].cpu().double(), generator)
            u, v = torch.rand(2, len(rows), 1, generator=generator, dtype=torch.float64)
            flip = (u + v) > 1
            u, v = torch.where(flip, 1 - u, u), torch.where(flip, 1 - v, v)
            tri = self.triangles[obj][face]
            points[rows] = tri[:, 0] + u * (tri[:, 1] - tri[:, 0]) + v * (tri[:, 2] - tri[:, 0])
            normals[rows] = self.normals[obj][face]
        return points, normals

    def _faces_by_group(self, obj: int, on_top: torch.Tensor, up: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """(len(on_top),) face indices: rows with ``on_top`` drawn by area among the top faces, the others among the rest."""
        top = self.normals[obj] @ up >= math.cos(math.radians(TOP_FACE_DEG))
        face = torch.zeros(len(on_top), dtype=torch.long)
        for rows, group in ((on_top, top), (~on_top, ~top)):
            count = int(rows.sum())
            if not count:
                continue
            weights = self.areas[obj] * group if bool(group.any()) and bool((~group).any()) else self.areas[obj]
            face[rows] = torch.multinomial(weights, count, replacement=True, generator=generator)
        return face


def _unit(v: torch.Tensor) -> torch.Tensor:
    return v / v.norm(dim=-1, keepdim=True).clamp(min=1e-12)


def _random_perpendicular(direction: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """Unit vectors (B, 3) perpendicular to ``direction``, uniformly distributed around it."""
    while True:
        r = torch.randn(direction.shape, generator=generator, dtype=direction.dtype)
        perp = r - (r * direction).sum(-1, keepdim=True) * direction
        if bool((perp.norm(dim=-1) > 1e-6).all()):
            return _unit(perp)


# A hull face whose outward normal is within this angle of the table's upward normal is on the object's top
# (``InitConfig.start_faces`` "top_and_sides"; the precision types' rim starts use the same, ``optim.type_starts``).
TOP_FACE_DEG = 30.0

# Redraws of starts whose palm lies below the table before giving up on a grasp's start (tabletop mode).
MAX_TABLE_REDRAWS = 100


class NoStartAboveTable(ValueError):
    """An object whose convex-hull starts all put the palm below its table."""


def _palm_origins(hulls: HullSampler, object_index, scale, config: InitConfig, generator, up=None) -> tuple[torch.Tensor, torch.Tensor]:
    """Palm origins (B, 3) and approach directions (B, 3): a hull point, a tilted inward approach, a distance back.
    ``up`` (B, 3): the table's normal per row, which splits the hull points between top and sides
    (``config.start_faces`` "top_and_sides"); None: every face by area."""
    batch = object_index.shape[0]
    point, normal = hulls.sample(object_index, generator, up=up if config.start_faces == "top_and_sides" else None)
    point = point * scale.cpu().double()[:, None]
    inward = -normal
    tilt = torch.rand(batch, 1, generator=generator, dtype=torch.float64) * math.radians(config.jitter_deg)
    approach = _unit(torch.cos(tilt) * inward + torch.sin(tilt) * _random_perpendicular(inward, generator))
    low, high = config.distance_m
    distance = low + (high - low) * torch.rand(batch, 1, generator=generator, dtype=torch.float64)
    return point - distance * approach, approach


def start_points(hulls: HullSampler, object_index, scale, config: InitConfig, generator, support=None) -> tuple[torch.Tensor, torch.Tensor]:
    """Palm origins (B, 3, m) and approach directions (B, 3): ``_palm_origins``, and on a table (``support``: normals (B, 3),
    offsets (B,) in m) every start whose palm origin lies below it drawn again (``NoStartAboveTable`` after
    ``MAX_TABLE_REDRAWS`` rounds)."""
    normal = None if support is None else support[0].detach().cpu().double()
    palm_origin, approach = _palm_origins(hulls, object_index, scale, config, generator, up=normal)
    if support is not None:
        offset = support[1].detach().cpu().double()
        for _ in range(MAX_TABLE_REDRAWS):
            below = ((palm_origin * normal).sum(-1) + offset < 0).nonzero(as_tuple=True)[0]
            if len(below) == 0:
                break
            palm_origin[below], approach[below] = _palm_origins(hulls, object_index.cpu()[below], scale.cpu()[below], config, generator,
                                                                up=normal[below])
        else:
            raise NoStartAboveTable(f"no start above the table after {MAX_TABLE_REDRAWS} redraws for {len(below)} grasps")
    return palm_origin, approach


def curled_pregrasp(hand: DescribedHand) -> torch.Tensor:
    """(J,) float64 the joints a hand from its MJCF starts around: ``START_CURL`` of the way from its open pre-grasp to
    each asymmetric joint's larger-magnitude limit (rad)."""
    limits = hand.joint_limits.cpu().double()
    open_pose = torch.as_tensor(hand.description.pregrasp, dtype=torch.float64)
    symmetric = (limits[:, 1].abs() - limits[:, 0].abs()).abs() < 1e-9
    flexed = torch.where(limits[:, 1].abs() > limits[:, 0].abs(), limits[:, 1], limits[:, 0])
    return torch.where(symmetric, open_pose, open_pose + START_CURL * (flexed - open_pose))


OPPOSING_DRAWS = 2000  # thumb joint vectors tried for the opposed start (``opposed_pregrasp``), drawn with a fixed seed


@functools.lru_cache(maxsize=8)
def opposed_pregrasp(hand: DescribedHand) -> torch.Tensor:
    """(J,) float64 the joints a hand from its MJCF starts around (rad): ``curled_pregrasp``, with each opposing finger's
    (the thumb's, ``HandDescription.opposing``) joints turned to face the other fingers: of ``OPPOSING_DRAWS`` vectors
    of its joints drawn uniformly in their ranges (fixed seed, so every run starts alike) and the curled vector itself,
    the one whose contact candidates' normals point most directly (mean cosine) at the centroid of the other fingers'
    candidates. Curling every joint toward its flexion limit does not oppose a thumb whose joints turn it out of the
    palm's plane: Allegro's curled thumb scores 0.93, LEAP's 0.90, opposed 0.96 and 0.98; on twelve household objects
    LEAP then held 49 of 192 grasps against 35 (six directions 31 against 20), Allegro 71 against 70."""
    joints = curled_pregrasp(hand)
    d = hand.description
    opposing = {hand.link_index[leaf] for leaf in d.opposing}
    fingers = [f for f, links in enumerate(hand.finger_links) if opposing & set(links)]
    if not fingers:
        return joints
    limits = hand.joint_limits.cpu().double()
    generator = torch.Generator().manual_seed(0)
    link = hand.contact_link.cpu()
    others = torch.ones_like(link, dtype=torch.bool) & (link != hand.link_index[hand.root_link])
    for f in fingers:
        others &= ~torch.isin(link, torch.tensor(hand.finger_links[f]))
    normals_local = torch.as_tensor(d.contact_normals, dtype=torch.float64)
    for f in fingers:
        moved = list(hand.finger_joints[f])
        on_finger = torch.isin(link, torch.tensor(hand.finger_links[f]))
        tries = joints.repeat(OPPOSING_DRAWS + 1, 1)
        low, high = limits[moved, 0], limits[moved, 1]
        tries[1:, moved] = low + (high - low) * torch.rand(OPPOSING_DRAWS, len(moved), generator=generator, dtype=torch.float64)
        with torch.no_grad():
            frames = hand.forward_parts_torch(torch.eye(3, dtype=hand.dtype).expand(len(tries), 3, 3), torch.zeros(len(tries), 3, dtype=hand.dtype),
                                              tries.to(hand.dtype))
            points = frames.transform(hand.contact_points_local, hand.contact_link).double()
            normals = torch.einsum("bcij,cj->bci", frames.rotation[:, hand.contact_link].double(), normals_local)
        toward = points[:, others].mean(dim=1, keepdim=True) - points[:, on_finger]
        facing = (normals[:, on_finger] * toward / toward.norm(dim=-1, keepdim=True).clamp(min=1e-12)).sum(-1).mean(dim=1)
        joints = tries[int(facing.argmax())]
    return joints


def _tip_centroid(hand: DescribedHand, points: torch.Tensor, fingers: list[int]) -> torch.Tensor:
    """(3,) the mean over ``fingers`` of each finger's tip: the centroid of the candidates (``points`` (C, 3)) on the last
    link of the finger that has candidates."""
    link = hand.contact_link.cpu()
    tips = []
    for f in fingers:
        last = next(l for l in reversed(hand.finger_links[f]) if bool((link == l).any()))
        tips.append(points[link == last].mean(dim=0))
    return torch.stack(tips).mean(dim=0)


@functools.lru_cache(maxsize=8)
def balanced_approach(hand: DescribedHand) -> np.ndarray:
    """(3,) unit, root frame: the direction a hand from its MJCF approaches an object along at its start, the one nearest
    its palm normal along which its thumb's tip and its other fingers' tips lie equally far (at ``opposed_pregrasp``: the
    palm normal with its component along the line from the thumb's tip to the fingertips' centroid removed). The Shadow
    Hand's palm normal tilted 30° toward the fingers (``approach_local(PALM_TILT_DEG)``) puts LEAP's curled fingertips 5.1
    cm, Allegro's 3.8 cm, ahead of the thumb's, so the fingers reach the object first and the thumb stays 6 cm off; this
    approach is LEAP's palm normal tilted 4° away from its fingers, Allegro's 7° toward them. A hand without an opposing
    finger keeps the 30° tilt."""
    opposing = {hand.link_index[leaf] for leaf in hand.description.opposing}
    thumbs = [f for f, links in enumerate(hand.finger_links) if opposing & set(links)]
    others = [f for f in range(len(hand.finger_links)) if f not in thumbs]
    if not thumbs or not others:
        return hand.approach_local(PALM_TILT_DEG)
    joints = opposed_pregrasp(hand)
    with torch.no_grad():
        frames = hand.forward_parts_torch(torch.eye(3, dtype=hand.dtype)[None], torch.zeros(1, 3, dtype=hand.dtype), joints[None].to(hand.dtype))
        points = frames.transform(hand.contact_points_local, hand.contact_link)[0].double().cpu()
    line = _tip_centroid(hand, points, others) - _tip_centroid(hand, points, thumbs)
    line = line / line.norm()
    normal = torch.tensor(hand.palm_frame_local[:3, 2], dtype=torch.float64)
    approach = normal - (normal @ line) * line
    return (approach / approach.norm()).numpy()


def described_start_poses(hand: DescribedHand, palm_origin: torch.Tensor, approach: torch.Tensor, config: InitConfig,
                          generator: torch.Generator) -> torch.Tensor:
    """(B, 6 + J) start poses of a hand from its MJCF (``hand.described``): its palm frame's origin at ``palm_origin``
    (B, 3, m), its approach (``balanced_approach``: thumb tip and fingertips equally far) along
    ``approach`` (B, 3) with a uniformly random roll, the joints drawn around its slightly curled pre-grasp with the
    thumb facing the fingers (``opposed_pregrasp``) with σ = ``joint_sigma_fraction`` of each range, clipped to the limits. Draws in the Shadow
    Hand's order."""
    batch = palm_origin.shape[0]
    hand_a = torch.tensor(balanced_approach(hand), dtype=torch.float64)
    hand_b = _unit(torch.linalg.cross(hand_a, torch.tensor(hand.palm_frame_local[:3, 1], dtype=torch.float64)))  # ⟂ a, in the palm's plane
    hand_frame = torch.stack([hand_a, hand_b, torch.linalg.cross(hand_a, hand_b)], dim=1)
    world_b = _random_perpendicular(approach, generator)
    world_frame = torch.stack([approach, world_b, torch.linalg.cross(approach, world_b)], dim=2)
    rotation = world_frame @ hand_frame.T
    origin_local = torch.tensor(hand.palm_frame_local[:3, 3], dtype=torch.float64)
    root_t = palm_origin - (rotation @ origin_local[:, None])[..., 0]
    limits = hand.joint_limits.cpu().double()
    sigma = config.joint_sigma_fraction * (limits[:, 1] - limits[:, 0])
    joints = opposed_pregrasp(hand) + sigma * torch.randn(batch, len(hand.joint_names), generator=generator, dtype=torch.float64)
    joints = torch.maximum(torch.minimum(joints, limits[:, 1]), limits[:, 0])
    return torch.cat([root_t, matrix_to_euler_xyz(rotation), joints], dim=1).to(hand.device, hand.dtype)


def initial_poses(
    hand: ShadowHand,
    hulls: HullSampler,
    object_index: torch.Tensor,
    scale: torch.Tensor,
    config: InitConfig,
    generator: torch.Generator,
    support: tuple[torch.Tensor, torch.Tensor] | None = None,
) -> torch.Tensor:
    """(B, 28) stored hand poses facing each grasp's object from outside its convex hull ((B, 6 + J) for a hand
    from its MJCF: ``described_start_poses``).

    ``support`` (tabletop mode): per grasp the table's normal (B, 3) and offset in metres (B,);
    starts with the palm origin below the table are redrawn (``NoStartAboveTable`` if some
    stay below after ``MAX_TABLE_REDRAWS`` rounds).
    """
    batch = object_index.shape[0]
    palm_origin, approach = start_points(hulls, object_index, scale, config, generator, support)
    if is_described(hand):
        return described_start_poses(hand, palm_origin, approach, config, generator)

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
