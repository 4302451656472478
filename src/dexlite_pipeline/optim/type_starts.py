"""Start poses of the precision grasp types (``optim.grasp_types``: pinch, tripod, lateral, rim).

A type's grasp centre c (midway between its two opposing sides' pads in its pre-grasp pose, palm frame), its opening
axis u (from the thumb side to the finger side), its opening w (the distance between the two sides' pads) and its
approach axis a (c's direction from the palm origin, made perpendicular to u: the object enters the opening from the
side away from the palm) are read off the hand's kinematics, for the type's aperture and along its pre-grasp blends
from closed to wide (``GraspType.pregrasp_joints``). For each start a target point p, an approach direction A and an
opening direction U ⟂ A are drawn in the object frame, preferably on a pair:

- **pair starts**: the object's opposing surface pairs (``PairSampler``: a surface point and the point straight across
  the object from it along its inward normal, with a facing normal) whose thickness fits the type's widest opening
  (less ``PAIR_CLEARANCE_M``), whose axis lies within ``PAIR_TILT_DEG`` of the table's plane and whose midpoint is
  ``PAD_HEIGHT_M`` above the table: a bowl's wall, a handle lying on the table, a box across its narrow side. p is the
  pair's midpoint, U its axis (thumb on either side at random) and A straight down for a start from above, or
  horizontal ⟂ U from the nearer side for one from the side; the midpoint must lie ``PAIR_DEPTH_M`` inside the convex
  hull behind it along A (the pads reach past the rim or edge, not deeper than fingertips go). The hand opens to the
  blend whose w is the thickness there plus a gap uniform in ``PAIR_GAP_M``, and c lies up to ``PAIR_BACKOFF_M`` back
  from p: the two pads start on either side of the object, a centimetre or so from it.
- otherwise (no usable pair for the start's approach) the earlier rule, with the aperture: from the side p a point of
  the convex hull (area-weighted, ``optim.init.HullSampler``), A its inward normal, U uniformly around A; from above
  (palm facing down) p a point of the object's rim, the hull edges where its upward-facing top (faces within
  ``TOP_FACE_DEG`` of the table's upward normal) meets the rest, sampled by length, A the downward normal, U horizontal
  across the rim (outward or inward at random); c lies ``centre_distance_m`` (uniform in the type's range) back from p.

Why pairs (measured on the household dataset's bowls, spatulas, hammers and cereal boxes, docs/results_journal.md,
2026-12-05): the rim rule put c 0.5–3 cm above the rim with the pads 7 cm apart, so on a bowl both pads started above
the rim and 3–4 cm from the wall (never on either side of it) and the optimizer pulled them onto the lip's top or the
bowl's bottom; on a spatula lying flat the pads started above the handle.

A is tilted by up to the type's ``jitter_deg`` about a random axis (U made perpendicular again) and the palm rotated so
that a → A and u → U. The joints are the start's pre-grasp pose plus noise of σ = ``joint_sigma_fraction`` of each
range, clipped to the limits. On a table a start whose palm origin or grasp centre would lie below it is drawn again
(target, directions and distance), as power starts are.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from dexlite_pipeline.hand.model import ShadowHand
from dexlite_pipeline.hand.rotation import matrix_to_euler_xyz
from dexlite_pipeline.objects.assets import ObjectAsset
from dexlite_pipeline.optim.grasp_types import GraspType, candidate_group
from dexlite_pipeline.optim.init import MAX_TABLE_REDRAWS, TOP_FACE_DEG, HullSampler, NoStartAboveTable

# Opposing surface pairs (``PairSampler``): this many surface points per object (area-weighted, the same for every run)
# look for the surface straight across the object from them, along their inward normal.
PAIR_SAMPLES = 2048
PAIR_SAMPLE_SEED = 0
# The far point's outward normal within this angle of the near point's reversed: two faces a pinch can squeeze.
PAIR_NORMAL_DEG = 30.0
# The object across a pair at most the type's opening (between its opposing pads in the aperture pose) minus this (m).
PAIR_CLEARANCE_M = 0.01
# A pair's axis within this angle of the table's plane: the pads close sideways, never one under the object.
PAIR_TILT_DEG = 30.0
# A pair's midpoint at least this far above the table (m): the thumb tip's radius, so the pads fit beside the object.
PAD_HEIGHT_M = 0.009
# A pair's midpoint this far inside the convex hull, measured back along the approach (m): the pads reach past the
# rim or edge they close on (not the lip's top), and not deeper than the fingertips reach.
PAIR_DEPTH_M = (0.008, 0.02)
# The grasp centre of a pair start lies up to this far back from the pair's midpoint along the approach (m).
PAIR_BACKOFF_M = 0.004
# A pair start opens the hand to the object's thickness there plus a gap uniform in this range (m, both sides together).
PAIR_GAP_M = (0.015, 0.03)
# Pre-grasp blends per half (closed to aperture, aperture to wide) among which a pair start picks its opening.
BLEND_STEPS = 20
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
    """A grasp type's grasp centre, opening axis and approach axis in the palm frame (module docstring), float64, in the
    aperture (``centre``, ``opening``, ``approach``, ``width``: the opening between the two sides' pads, m) and along
    its pre-grasp blends (``GraspType.pregrasp_joints``; ``blends`` (K,), ``joints`` (K, J), ``centres``, ``openings``,
    ``approaches`` (K, 3), ``widths`` (K,); one blend, the aperture, for a type without closed and wide poses)."""

    def __init__(self, hand: ShadowHand, grasp_type: GraspType) -> None:
        if grasp_type.opposition is None:
            raise ValueError(f"grasp type {grasp_type.name} has no opposing sides (its starts are the convex-hull starts)")
        self.blends = torch.linspace(0.0, 2.0, 2 * BLEND_STEPS + 1, dtype=torch.float64) if grasp_type.closed else torch.ones(1, dtype=torch.float64)
        self.joints = torch.stack([grasp_type.pregrasp_joints(float(b)) for b in self.blends])
        pose = torch.zeros(len(self.blends), 6 + self.joints.shape[1], dtype=hand.dtype, device=hand.device)
        pose[:, 6:] = self.joints.to(hand.dtype)
        frames = hand.forward(pose)
        table = frames.transform(hand.all_contact_points_local, hand.all_contact_link).double().cpu()
        sides = [table[:, [i for group in side for i in candidate_group(hand, group)]].mean(1) for side in grasp_type.opposition]
        self.centres = (sides[0] + sides[1]) / 2
        self.openings = _unit(sides[1] - sides[0])
        self.widths = (sides[1] - sides[0]).norm(dim=-1)
        self.approaches = _unit(_perpendicular_part(self.centres, self.openings))
        self.aperture_index = int((self.blends - 1.0).abs().argmin())
        k = self.aperture_index
        self.centre, self.opening, self.approach, self.width = self.centres[k], self.openings[k], self.approaches[k], float(self.widths[k])
        self.max_width = float(self.widths.max())

    def fitting(self, width_m: torch.Tensor) -> torch.Tensor:
        """(B,) the blend index whose opening is nearest each of ``width_m`` (B,)."""
        return (self.widths[None] - width_m[:, None]).abs().argmin(dim=1)

    def hand_frames(self, index: torch.Tensor) -> torch.Tensor:
        """(B, 3, 3) columns: the approach, opening and their cross product of the blends ``index`` (palm frame)."""
        a, u = self.approaches[index], self.openings[index]
        return torch.stack([a, u, torch.linalg.cross(a, u)], dim=2)


class PairSampler:
    """Per object, pairs of opposing surface points across it (normalized frame): the places a precision grasp can
    squeeze between its two sides, e.g. a bowl's wall, a handle lying on the table or a box across its narrow side.

    ``PAIR_SAMPLES`` area-weighted surface points each cast a ray along their inward normal; where it leaves the
    object again, with that face's normal opposing theirs within ``PAIR_NORMAL_DEG``, the two points are a pair:
    its midpoint, its unit axis (near to far point) and its length (the object's thickness there)."""

    def __init__(self, assets: list[ObjectAsset]) -> None:
        self.assets = assets
        self._pairs: dict[int, tuple[torch.Tensor, torch.Tensor, torch.Tensor]] = {}

    def pairs(self, obj: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Object ``obj``'s pairs: midpoints (P, 3), axes (P, 3), lengths (P,), normalized frame, float64."""
        if obj not in self._pairs:
            import trimesh

            mesh = self.assets[obj].load_mesh()
            points, faces = trimesh.sample.sample_surface(mesh, PAIR_SAMPLES, seed=PAIR_SAMPLE_SEED)
            normals = np.asarray(mesh.face_normals)[faces]
            origin = points - 1e-6 * float(mesh.scale) * normals
            hits, ray, hit_face = mesh.ray.intersects_location(origin, -normals, multiple_hits=False)
            opposing = (np.asarray(mesh.face_normals)[hit_face] * normals[ray]).sum(1) <= -math.cos(math.radians(PAIR_NORMAL_DEG))
            near, far = points[ray][opposing], hits[opposing]
            order = np.argsort(ray[opposing], kind="stable")  # ray order: the same pairs whatever the backend's hit order
            near, far = near[order], far[order]
            length = np.linalg.norm(far - near, axis=1)
            keep = length > 0
            axis = (far - near)[keep] / length[keep, None]
            self._pairs[obj] = tuple(torch.as_tensor(a, dtype=torch.float64) for a in ((near + far)[keep] / 2, axis, length[keep]))
        return self._pairs[obj]


def _hull_exit(hull_planes: tuple[torch.Tensor, torch.Tensor], point: torch.Tensor, direction: torch.Tensor) -> torch.Tensor:
    """(P,) distance from ``point`` (P, 3) along unit ``direction`` (P, 3) to where it leaves the convex hull given by its
    face planes (outward normals (F, 3), offsets (F,): n·x ≤ offset inside); 0 for a point already outside."""
    normals, offsets = hull_planes
    along = direction @ normals.T  # (P, F)
    room = offsets[None] - point @ normals.T
    exit_at = torch.where(along > 1e-12, room / along.clamp(min=1e-12), torch.full_like(room, math.inf))
    return exit_at.min(dim=1).values.clamp(min=0.0)


class RimSampler:
    """Per object, the rim of its convex hull's top (module docstring): edge segments and the horizontal direction
    across each (normalized frame), for the object's upward normal."""

    def __init__(self, assets: list[ObjectAsset], up: list[tuple[float, float, float]]) -> None:
        self.hulls = [asset.load_mesh().convex_hull for asset in assets]
        self.up = [np.asarray(u, dtype=np.float64) / np.linalg.norm(u) for u in up]
        self.pairs = PairSampler(assets)
        self.planes = [(torch.tensor(np.asarray(h.face_normals), dtype=torch.float64),
                        torch.as_tensor((np.asarray(h.face_normals) * np.asarray(h.triangles)[:, 0]).sum(1), dtype=torch.float64))
                       for h in self.hulls]  # fmt: skip
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


def _pair_targets(rims: RimSampler, obj: int, scale: torch.Tensor, above: torch.Tensor, opening_m: float,
                  table_offset_m: torch.Tensor | None, generator: torch.Generator) -> tuple[torch.Tensor, ...]:
    """Pair starts (module docstring) for one object: per start whether it has one (B,) bool, its target point, the
    pair's midpoint (B, 3, metres), approach A and opening U (B, 3) and the object's thickness across the pair (B,
    metres; rows without a pair: zeros).

    A start from above (``above``) takes a pair whose midpoint lies ``PAIR_DEPTH_M`` below the hull's top straight
    above it, A the downward normal; one from the side a pair whose midpoint lies that far inside the hull along a
    horizontal A ⟂ the pair's axis (from the nearer side). U is the pair's axis, either way round. Pairs are those at
    most ``opening_m`` (the type's widest opening) − ``PAIR_CLEARANCE_M`` across at the start's scale, within ``PAIR_TILT_DEG`` of the table's
    plane and with the midpoint ``PAD_HEIGHT_M`` above the table (``table_offset_m``: the table's offset per start,
    metres; None: no table)."""
    count = scale.shape[0]
    found = torch.zeros(count, dtype=torch.bool)
    point, approach, opening = (torch.zeros(count, 3, dtype=torch.float64) for _ in range(3))
    thickness = torch.zeros(count, dtype=torch.float64)
    mid, axis, length = rims.pairs.pairs(obj)
    if not len(length):
        return found, point, approach, opening, thickness
    up = torch.as_tensor(rims.up[obj], dtype=torch.float64)
    flat = (axis @ up).abs() <= math.sin(math.radians(PAIR_TILT_DEG))
    side_dir = _unit(torch.linalg.cross(up.expand_as(axis), axis))  # horizontal, ⟂ the axis
    exit_up = _hull_exit(rims.planes[obj], mid, up.expand_as(mid))
    exit_plus, exit_minus = (_hull_exit(rims.planes[obj], mid, sign * side_dir) for sign in (1.0, -1.0))
    side_sign = (exit_plus <= exit_minus).double() * 2 - 1  # the approach comes from the nearer side
    exit_side = torch.minimum(exit_plus, exit_minus)
    for s in torch.unique(scale).tolist():
        at = (scale == s).nonzero(as_tuple=True)[0]
        fits = flat & (length * s <= opening_m - PAIR_CLEARANCE_M)
        if table_offset_m is not None:
            fits &= (mid @ up) * s + float(table_offset_m[at].min()) >= PAD_HEIGHT_M
        low, high = PAIR_DEPTH_M
        for from_above, exit_dist in ((True, exit_up), (False, exit_side)):
            rows = at[above[at] == from_above]
            usable = (fits & (exit_dist * s >= low) & (exit_dist * s <= high)).nonzero(as_tuple=True)[0]
            if not len(rows) or not len(usable):
                continue
            pick = usable[torch.randint(len(usable), (len(rows),), generator=generator)]
            found[rows] = True
            point[rows] = mid[pick] * s
            approach[rows] = -up.expand(len(rows), 3) if from_above else -side_sign[pick, None] * side_dir[pick]
            opening[rows] = axis[pick]
            thickness[rows] = length[pick] * s
    flip = torch.where(torch.rand(count, 1, generator=generator, dtype=torch.float64) < 0.5, -1.0, 1.0)  # thumb on either side
    return found, point, approach, flip * opening, thickness


def _targets(grasp_type: GraspType, hulls: HullSampler, rims: RimSampler, obj: int, scale: torch.Tensor,
             table_height_m: float | None, generator: torch.Generator, opening_m: float | None = None,
             table_offset_m: torch.Tensor | None = None) -> tuple[torch.Tensor, ...]:
    """Target points (B, 3, metres), approach directions A (B, 3), opening directions U (B, 3), whether each is a pair
    start (B,) and the object's thickness across its pair (B, metres; 0 without) for one object: pair starts where the
    object has a usable pair (``opening_m``: the type's widest opening; None: none), the rim and hull starts otherwise."""
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
    point = point * scale[:, None]
    paired, thickness = torch.zeros(count, dtype=torch.bool), torch.zeros(count, dtype=torch.float64)
    if opening_m is not None:
        paired, pair_point, pair_approach, pair_opening, thickness = _pair_targets(rims, obj, scale, above, opening_m, table_offset_m, generator)
        point = torch.where(paired[:, None], pair_point, point)
        approach = torch.where(paired[:, None], pair_approach, approach)
        opening = torch.where(paired[:, None], pair_opening, opening)
    approach = _tilted(approach, grasp_type.jitter_deg, generator)
    opening = _unit(_perpendicular_part(opening, approach))
    return point, approach, opening, paired, thickness


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
    """(B, 6 + J) stored start poses of ``grasp_type`` (the Shadow Hand's 28) (module docstring), object by object in order of first appearance.

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
    blend = torch.full((batch,), geometry.aperture_index, dtype=torch.long)  # each start's pre-grasp opening
    low, high = grasp_type.centre_distance_m
    for obj in dict.fromkeys(index.tolist()):
        rows = (index == obj).nonzero(as_tuple=True)[0]
        height = None if support is None else rims.height[obj] * float(scale[rows].max())
        pending = torch.arange(len(rows))
        for _ in range(MAX_TABLE_REDRAWS):
            r = rows[pending]
            point, a, u, paired, thickness = _targets(grasp_type, hulls, rims, obj, scale[r], height, generator, geometry.max_width,
                                                      None if support is None else offset[r])
            u01, gap = torch.rand(2, len(r), generator=generator, dtype=torch.float64)
            d = torch.where(paired, PAIR_BACKOFF_M * u01, low + (high - low) * u01)[:, None]
            k = torch.where(paired, geometry.fitting(thickness + PAIR_GAP_M[0] + (PAIR_GAP_M[1] - PAIR_GAP_M[0]) * gap), geometry.aperture_index)
            centre_target[r], approach[r], opening[r], distance[r], blend[r] = point, a, u, d, k
            if support is None:
                break
            centre = point - d * a
            world_frame = torch.stack([a, u, torch.linalg.cross(a, u)], dim=2)
            palm = centre - (world_frame @ geometry.hand_frames(k).transpose(1, 2) @ geometry.centres[k][..., None])[..., 0]
            height_of = lambda x, r=r: (x * normal[r]).sum(-1) + offset[r]  # noqa: E731
            pending = pending[(height_of(palm) < 0) | (height_of(centre) < 0)]
            if not len(pending):
                break
        else:
            raise NoStartAboveTable(f"no start above the table after {MAX_TABLE_REDRAWS} redraws for {len(pending)} grasps")
    world_frame = torch.stack([approach, opening, torch.linalg.cross(approach, opening)], dim=2)
    rotation = world_frame @ geometry.hand_frames(blend).transpose(1, 2)
    palm_origin = centre_target - distance * approach - (rotation @ geometry.centres[blend][..., None])[..., 0]
    limits = hand.joint_limits.cpu().double()
    sigma = joint_sigma_fraction * (limits[:, 1] - limits[:, 0])
    joints = geometry.joints[blend] + sigma * torch.randn(batch, geometry.joints.shape[1], generator=generator, dtype=torch.float64)
    joints = torch.maximum(torch.minimum(joints, limits[:, 1]), limits[:, 0])
    pose = torch.cat([palm_origin, matrix_to_euler_xyz(rotation), joints], dim=1)
    return pose.to(hand.device, hand.dtype)
