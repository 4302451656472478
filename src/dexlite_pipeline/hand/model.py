"""Batched, differentiable Shadow Hand kinematics and collision geometry (torch).

The kinematic tree is read once from the palm-rooted MuJoCo model (``hand.mjcf``) into
flat tensors; forward kinematics then runs over a batch of 28-vectors with no Python
work per grasp. pytorch-kinematics 0.10 cannot parse MJCF under mujoco 4, so the chain is
built here from the compiled MjModel; ``tests/hand`` checks it against MuJoCo's forward
kinematics and against pytorch-kinematics on the same chain (``hand.pk_chain``; speeds:
``benchmarks/timing/bench_kinematics.py``).

Frames: ``hand_pose`` = [t (3, m), static-xyz Euler (3, rad), 22 joints (rad)] is the pose
of ``robot0:palm`` in the object frame. Every point set below is returned in the object frame.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import torch

from dexlite_pipeline.hand.mjcf import hand_mjcf_string
from dexlite_pipeline.hand.rotation import axis_angle_to_matrix, euler_xyz_to_matrix, quat_wxyz_to_matrix

JOINT_NAMES: tuple[str, ...] = tuple(
    f"robot0:{name}"
    for name in (
        "FFJ3 FFJ2 FFJ1 FFJ0 MFJ3 MFJ2 MFJ1 MFJ0 RFJ3 RFJ2 RFJ1 RFJ0 "
        "LFJ4 LFJ3 LFJ2 LFJ1 LFJ0 THJ4 THJ3 THJ2 THJ1 THJ0"
    ).split()
)
POSE_DIM = 28
TRANSLATION = slice(0, 3)
ROTATION = slice(3, 6)
JOINTS = slice(6, 28)

FINGER_CONTACT_LINKS = tuple(
    f"robot0:{finger}{segment}" for finger in ("ff", "mf", "rf", "lf") for segment in ("proximal", "middle", "distal")
) + ("robot0:thmiddle", "robot0:thdistal")
DISTAL_LINKS = ("robot0:ffdistal", "robot0:mfdistal", "robot0:rfdistal", "robot0:lfdistal", "robot0:thdistal")
# The side of a finger that a lateral (key) pinch presses on: the index finger's middle phalanx, on its radial side
# (+x of the link, toward the thumb). Its candidates follow the palmar pads in the contact table (``all_contact_*``).
SIDE_CONTACT_LINKS = ("robot0:ffmiddle",)
# Directions of the side candidates' columns in the link's x-y plane, radians from +x toward the palmar side (−y).
SIDE_CONTACT_ANGLES = (0.0, -math.radians(30.0))
# The thumb's tip: candidates on the hemispherical end of the thumb's distal capsule, on its palmar side (−x), where a
# pinch or tripod on a thin wall or handle touches (15–19 mm out from the capsule's centre, beyond the pads' last row at
# 8 mm: docs/results_journal.md, 2026-12-05). They follow the side candidates in the contact table (``all_contact_*``).
TIP_CONTACT_LINKS = ("robot0:thdistal",)
# Rows of the tip candidates: angles from the capsule's axis (+z, toward the tip), degrees; 90 is where the cap meets
# the cylinder, 18 about 0.45 mm short of the tip along the axis (2.9 mm from the tip's point on the surface).
TIP_CONTACT_POLAR_DEG = (90.0, 72.0, 54.0, 36.0, 18.0)
# Columns of the tip candidates about the axis, degrees off the palmar direction (the pads' columns: ±25°).
TIP_CONTACT_AZIMUTH_DEG = (-25.0, 25.0)
# Kinds of the entries of the contact table, in its order: palmar pads, side candidates, thumb-tip candidates.
PAD, SIDE, TIP = "pad", "side", "tip"

CAPSULE, BOX = 0, 1


@dataclass(frozen=True)
class HandFrames:
    """Link frames in the object frame: rotation (B, L, 3, 3), translation (B, L, 3)."""

    rotation: torch.Tensor
    translation: torch.Tensor

    def transform(self, local_points: torch.Tensor, link_index: torch.Tensor) -> torch.Tensor:
        """Map points given in their link's frame, (P, 3) with link ids (P,), to (B, P, 3)."""
        rot = self.rotation[:, link_index]  # (B, P, 3, 3)
        return (rot * local_points[None, :, None, :]).sum(-1) + self.translation[:, link_index]


def _rotate(rotation: torch.Tensor, vector: torch.Tensor) -> torch.Tensor:
    """Batched rotation (..., 3, 3) applied to vectors (..., 3).

    A matmul, not broadcasting: the faster of the two for these 3x3 products on CPU (torch 2.13).
    """
    return (rotation @ vector[..., None])[..., 0]


class ShadowHand:
    """The Shadow Hand rooted at the palm: kinematics, point sets and collision shapes."""

    def __init__(
        self,
        device: torch.device | str = "cpu",
        dtype: torch.dtype = torch.float32,
        contacts_per_link: int = 10,
        surface_points_per_shape: int = 64,
    ) -> None:
        import mujoco

        self.device = torch.device(device)
        self.dtype = dtype
        model = mujoco.MjModel.from_xml_string(hand_mjcf_string())
        self._mj_model = model
        names = [model.body(b).name for b in range(1, model.nbody)]
        self.link_names: tuple[str, ...] = tuple(names)
        self.link_index = {name: i for i, name in enumerate(names)}
        self.joint_names = JOINT_NAMES
        mj_joint_names = [model.joint(j).name for j in range(model.njnt)]
        if tuple(mj_joint_names) != JOINT_NAMES:
            raise RuntimeError(f"unexpected Shadow Hand joint order in the gym model: {mj_joint_names}")
        self.joint_limits = torch.tensor(model.jnt_range, dtype=dtype, device=self.device)  # (22, 2)

        body_joint = np.full(len(names), -1)
        for j in range(model.njnt):
            body_joint[model.jnt_bodyid[j] - 1] = j
        self._parent = [int(model.body_parentid[b]) - 1 for b in range(1, model.nbody)]
        self._body_joint = body_joint.tolist()
        as_t = functools.partial(torch.as_tensor, dtype=dtype, device=self.device)
        self._offset_pos = as_t(model.body_pos[1:].copy())
        self._offset_rot = quat_wxyz_to_matrix(as_t(model.body_quat[1:].copy()))
        self._offset_is_identity = [bool(np.allclose(q, [1, 0, 0, 0])) for q in model.body_quat[1:]]
        self._joint_axis = as_t(model.jnt_axis.copy())
        self._joint_pos = as_t(model.jnt_pos.copy())
        if np.abs(model.jnt_pos).max() > 0:
            raise RuntimeError("joint anchors off the body origin are not supported")
        self._build_levels()
        self._kinematics = None  # ``kinematics_kernel.HandKinematics``, built on the first CPU call

        self._build_shapes(model, as_t)
        self._build_point_sets(as_t, contacts_per_link, surface_points_per_shape)

    def _build_levels(self) -> None:
        """Group the links by depth in the tree, so FK runs one batched step per level, not per link.

        The five fingers hang side by side, so 23 links take 6 steps. A level holds its
        links, their positions among the previous level's links (the palm frame is level −1)
        and whether any has a rotated offset or a joint. Joint angles are gathered once
        in level order (a link without a joint gets angle 0, i.e. the identity), and
        ``_link_order`` puts the concatenated levels back in link order.
        """
        depth: list[int] = []
        for parent in self._parent:  # MuJoCo lists every parent before its children
            depth.append(0 if parent < 0 else depth[parent] + 1)
        position: dict[int, int] = {}
        self._levels = []
        order: list[int] = []
        joint_columns: list[int] = []
        for d in range(max(depth) + 1):
            links = [b for b in range(len(depth)) if depth[b] == d]
            parents = [0 if self._parent[b] < 0 else position[self._parent[b]] for b in links]
            position.update({b: i for i, b in enumerate(links)})
            jointed = any(self._body_joint[b] >= 0 for b in links)
            if jointed:
                joint_columns += [self._body_joint[b] if self._body_joint[b] >= 0 else len(self.joint_names) for b in links]
            self._levels.append({
                "offset_pos": self._offset_pos[links],
                "offset_rot": self._offset_rot[links],
                "parents": torch.tensor(parents, device=self.device),
                "rotated": not all(self._offset_is_identity[b] for b in links),  # else R·I is skipped (exact either way)
                "jointed": jointed,
                "size": len(links),
            })
            order += links
        self._link_order = torch.argsort(torch.tensor(order, device=self.device))
        self._level_joint_column = torch.tensor(joint_columns, device=self.device)
        axis_or_none = torch.cat([self._joint_axis, self._joint_axis.new_tensor([[0.0, 0.0, 1.0]])])
        self._level_joint_axis = axis_or_none[self._level_joint_column]

    # ----------------------------------------------------------------- geometry
    def _build_shapes(self, model, as_t) -> None:
        kinds, links, pos, rot, size = [], [], [], [], []
        for g in range(model.ngeom):
            if model.geom_group[g] != 4 or model.geom_contype[g] == 0:
                continue
            gtype = int(model.geom_type[g])
            if gtype == int(mujoco_geom("capsule")):
                kinds.append(CAPSULE)
                r, half = model.geom_size[g][:2]
                size.append([r, half, 0.0])
            elif gtype == int(mujoco_geom("box")):
                kinds.append(BOX)
                size.append(list(model.geom_size[g]))
            else:
                raise RuntimeError(f"unexpected collision geom type {gtype} in the hand model")
            links.append(int(model.geom_bodyid[g]) - 1)
            pos.append(model.geom_pos[g].copy())
            rot.append(model.geom_quat[g].copy())
        self._set_shapes(kinds, links, as_t(np.array(pos)), quat_wxyz_to_matrix(as_t(np.array(rot))), as_t(np.array(size)))

    def _set_shapes(self, kinds: list[int], links: list[int], pos: torch.Tensor, rot: torch.Tensor, size: torch.Tensor) -> None:
        """The collision shapes' tensors: kind (CAPSULE/BOX), link, position (m) and rotation (3x3) in the link frame,
        size (m), the ids of each kind and each shape's bounding radius about its centre (m, for exact culling)."""
        self.shape_kind = torch.tensor(kinds, device=self.device)
        self.shape_link = torch.tensor(links, device=self.device)
        self.shape_pos, self.shape_rot, self.shape_size = pos, rot, size
        self.capsule_ids = torch.nonzero(self.shape_kind == CAPSULE).flatten()
        self.box_ids = torch.nonzero(self.shape_kind == BOX).flatten()
        cap_r = self.shape_size[:, 0] + self.shape_size[:, 1]
        box_r = self.shape_size.norm(dim=-1)
        self.shape_bounding_radius = torch.where(self.shape_kind == CAPSULE, cap_r, box_r)

    def _capsule_of_link(self, link: str) -> int:
        link_id = self.link_index[link]
        for s in self.capsule_ids.tolist():
            if int(self.shape_link[s]) == link_id:
                return s
        raise KeyError(link)

    def _build_point_sets(self, as_t, contacts_per_link: int, surface_per_shape: int) -> None:
        # Contact candidates: on the palmar side of each finger capsule (-y; -x for the thumb).
        heights = max(contacts_per_link // 2, 1)
        pts, ids = [], []
        for link in FINGER_CONTACT_LINKS:
            s = self._capsule_of_link(link)
            r, half = float(self.shape_size[s, 0]), float(self.shape_size[s, 1])
            palmar = math.pi if link.startswith("robot0:th") else -math.pi / 2  # palmar normal angle in x-y
            zc = float(self.shape_pos[s, 2])
            for k in range(contacts_per_link):
                h = k % heights
                side = (k // heights) * 2 - 1 if contacts_per_link > 1 else 0
                angle = palmar + side * math.radians(25.0)
                z = zc - half * 0.8 + 1.6 * half * (h + 0.5) / heights
                pts.append([r * math.cos(angle), r * math.sin(angle), z])
                ids.append(self.link_index[link])
        self.contact_points_local = as_t(np.array(pts))
        self.contact_link = torch.tensor(ids, device=self.device)

        # Side candidates (``SIDE_CONTACT_LINKS``): columns at ``SIDE_CONTACT_ANGLES``, at the pads' heights.
        pts, ids = [], []
        for link in SIDE_CONTACT_LINKS:
            s = self._capsule_of_link(link)
            r, half, zc = float(self.shape_size[s, 0]), float(self.shape_size[s, 1]), float(self.shape_pos[s, 2])
            for angle in SIDE_CONTACT_ANGLES:
                for h in range(heights):
                    pts.append([r * math.cos(angle), r * math.sin(angle), zc - half * 0.8 + 1.6 * half * (h + 0.5) / heights])
                    ids.append(self.link_index[link])
        self.side_contact_points_local = as_t(np.array(pts))
        self.side_contact_link = torch.tensor(ids, device=self.device)
        self.tip_contact_points_local, self.tip_contact_link = self._tip_candidates(as_t)

        # Penetration keypoints on capsule axes, 1 cm in from the ends, ~1.2 cm apart.
        pts, ids = [], []
        for s in self.capsule_ids.tolist():
            zc, half = float(self.shape_pos[s, 2]), float(self.shape_size[s, 1])
            lo, hi = zc - half + 0.01, zc + half - 0.01
            count = max(1, int(round((hi - lo) / 0.012)) + 1) if hi > lo else 1
            zs = [zc] if hi <= lo else np.linspace(lo, hi, count).tolist()
            for z in zs:
                pts.append([0.0, 0.0, z])
                ids.append(int(self.shape_link[s]))
        for s in self.box_ids.tolist():
            hx, _, hz = self.shape_size[s].tolist()
            cx, cy, cz = self.shape_pos[s].tolist()
            for fx in (-0.5, 0.5):
                for fz in (-0.5, 0.5):
                    pts.append([cx + fx * hx, cy, cz + fz * hz])
                    ids.append(int(self.shape_link[s]))
        self.keypoints_local = as_t(np.array(pts))
        self.keypoint_link = torch.tensor(ids, device=self.device)
        self.keypoint_pair_mask = self._keypoint_pair_mask()

        # Surface points on every collision shape, evenly spread (deterministic).
        pts, ids = [], []
        for s in range(len(self.shape_kind)):
            local = _shape_surface_samples(int(self.shape_kind[s]), self.shape_size[s].tolist(), surface_per_shape)
            world = local @ self.shape_rot[s].cpu().numpy().T + self.shape_pos[s].cpu().numpy()
            pts.append(world)
            ids.extend([int(self.shape_link[s])] * len(world))
        self.surface_points_local = as_t(np.concatenate(pts))
        self.surface_link = torch.tensor(ids, device=self.device)

    def _tip_candidates(self, as_t) -> tuple[torch.Tensor, torch.Tensor]:
        """Candidates on the tip cap of each ``TIP_CONTACT_LINKS`` capsule (link frame, m, and link ids): a point on the
        sphere of the capsule's radius about the end of its axis segment (+z end), at ``TIP_CONTACT_POLAR_DEG`` from the
        axis and ``TIP_CONTACT_AZIMUTH_DEG`` about it from the palmar direction (−x, as the thumb's pads), row by row."""
        pts, ids = [], []
        for link in TIP_CONTACT_LINKS:
            s = self._capsule_of_link(link)
            r, half, zc = float(self.shape_size[s, 0]), float(self.shape_size[s, 1]), float(self.shape_pos[s, 2])
            for polar in TIP_CONTACT_POLAR_DEG:
                for azimuth in TIP_CONTACT_AZIMUTH_DEG:
                    theta, phi = math.radians(polar), math.pi + math.radians(azimuth)
                    pts.append([r * math.sin(theta) * math.cos(phi), r * math.sin(theta) * math.sin(phi), zc + half + r * math.cos(theta)])
                    ids.append(self.link_index[link])
        return as_t(np.array(pts).reshape(-1, 3)), torch.tensor(ids, dtype=torch.long, device=self.device)

    def _keypoint_pair_mask(self) -> torch.Tensor:
        """Pairs counted by E_spen: keypoints on different links that are not parent and child."""
        link = self.keypoint_link.tolist()
        parent = self._parent
        n = len(link)
        mask = torch.zeros(n, n, dtype=torch.bool, device=self.device)
        for i in range(n):
            for j in range(i + 1, n):
                a, b = link[i], link[j]
                adjacent = a == b or parent[a] == b or parent[b] == a or (parent[a] == parent[b] and parent[a] >= 0 and _is_zero_length(self, a, b))
                mask[i, j] = mask[j, i] = not adjacent
        return mask

    # --------------------------------------------------------------- kinematics
    def palm_frame(self, hand_pose: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Rotation (B, 3, 3) and translation (B, 3) of the palm in the object frame."""
        return euler_xyz_to_matrix(hand_pose[..., ROTATION]), hand_pose[..., TRANSLATION]

    def forward(self, hand_pose: torch.Tensor) -> HandFrames:
        """All link frames in the object frame for a (B, 28) batch of hand poses."""
        palm_rot, palm_t = self.palm_frame(hand_pose)
        return self.forward_parts(palm_rot, palm_t, hand_pose[..., JOINTS])

    def forward_parts(self, palm_rot: torch.Tensor, palm_t: torch.Tensor, joints: torch.Tensor) -> HandFrames:
        """Like ``forward`` with the palm rotation given as a matrix (for 6D optimizers).

        On the CPU, compiled (``hand.kinematics_kernel``, forward and backward); elsewhere ``forward_parts_torch``.
        """
        if palm_rot.device.type == "cpu":
            if self._kinematics is None:
                from dexlite_pipeline.hand.kinematics_kernel import HandKinematics  # imports numba: only when used

                self._kinematics = HandKinematics(self._parent, self._offset_pos, self._offset_rot, self._body_joint, self._joint_axis)
            return HandFrames(*self._kinematics.forward(palm_rot, palm_t, joints))
        return self.forward_parts_torch(palm_rot, palm_t, joints)

    def forward_parts_torch(self, palm_rot: torch.Tensor, palm_t: torch.Tensor, joints: torch.Tensor) -> HandFrames:
        """``forward_parts`` as torch operations, on any device.

        Each link: R = R_parent · R_offset · R_joint(q), t = t_parent + R_parent · p_offset,
        computed a tree level at a time (see ``_build_levels``).
        """
        angles = torch.cat([joints, joints.new_zeros(joints.shape[0], 1)], dim=1).index_select(1, self._level_joint_column)
        joint_rots = iter(axis_angle_to_matrix(self._level_joint_axis, angles).split(
            [level["size"] for level in self._levels if level["jointed"]], dim=1))
        rot, t = palm_rot[:, None], palm_t[:, None]
        rots: list[torch.Tensor] = []
        trans: list[torch.Tensor] = []
        for level in self._levels:
            parent_rot, parent_t = rot.index_select(1, level["parents"]), t.index_select(1, level["parents"])
            t = parent_t + _rotate(parent_rot, level["offset_pos"])
            rot = parent_rot @ level["offset_rot"] if level["rotated"] else parent_rot
            if level["jointed"]:
                rot = rot @ next(joint_rots)
            rots.append(rot)
            trans.append(t)
        rotation = torch.cat(rots, dim=1).index_select(1, self._link_order)
        return HandFrames(rotation, torch.cat(trans, dim=1).index_select(1, self._link_order))

    def link_poses(self, hand_pose: torch.Tensor) -> dict[str, torch.Tensor]:
        """Link name -> (B, 4, 4) homogeneous pose of each body frame in the object frame."""
        frames = self.forward(hand_pose)
        batch = hand_pose.shape[0]
        out = {}
        for i, name in enumerate(self.link_names):
            m = torch.zeros(batch, 4, 4, dtype=hand_pose.dtype, device=hand_pose.device)
            m[:, :3, :3] = frames.rotation[:, i]
            m[:, :3, 3] = frames.translation[:, i]
            m[:, 3, 3] = 1.0
            out[name] = m
        return out

    # ---------------------------------------------------------------- point sets
    @property
    def pad_candidate_count(self) -> int:
        """How many palmar pad candidates there are (140): contact indices below it are pads, from it on other kinds."""
        return len(self.contact_link)

    @property
    def all_contact_points_local(self) -> torch.Tensor:
        """(140 + S + T, 3) the contact table a contact index points into: the palmar pads (0–139), the side candidates
        (140–149), the thumb-tip candidates (150–159); appended, so a pad's index never changes."""
        return torch.cat([self.contact_points_local, self.side_contact_points_local, self.tip_contact_points_local])

    @property
    def all_contact_link(self) -> torch.Tensor:
        """(140 + S + T,) the link of each entry of ``all_contact_points_local``."""
        return torch.cat([self.contact_link, self.side_contact_link, self.tip_contact_link])

    @property
    def contact_kinds(self) -> tuple[str, ...]:
        """The kind (``PAD``, ``SIDE``, ``TIP``) of each entry of the contact table."""
        return (PAD,) * len(self.contact_link) + (SIDE,) * len(self.side_contact_link) + (TIP,) * len(self.tip_contact_link)

    def candidates_on(self, links: tuple[str, ...], kind: str | None = None) -> tuple[int, ...]:
        """Indices into the contact table (``all_contact_points_local``) of every candidate on the named links (of the
        given kind only, if any)."""
        wanted = {self.link_index[name] for name in links}
        kinds = self.contact_kinds
        return tuple(i for i, link in enumerate(self.all_contact_link.tolist()) if link in wanted and kind in (None, kinds[i]))

    def contact_candidates(self, frames: HandFrames) -> torch.Tensor:
        """(B, 140, 3) contact candidate points on the palmar side of the finger links."""
        return frames.transform(self.contact_points_local, self.contact_link)

    def penetration_keypoints(self, frames: HandFrames) -> torch.Tensor:
        """(B, K, 3) self-collision keypoints; pair them with ``keypoint_pair_mask``."""
        return frames.transform(self.keypoints_local, self.keypoint_link)

    def surface_points(self, frames: HandFrames) -> torch.Tensor:
        """(B, S, 3) points on the surface of the collision shapes."""
        return frames.transform(self.surface_points_local, self.surface_link)

    def shape_frames(self, frames: HandFrames) -> tuple[torch.Tensor, torch.Tensor]:
        """Rotation (B, S, 3, 3) and centre (B, S, 3) of every collision shape."""
        link_rot = frames.rotation[:, self.shape_link]
        rot = link_rot @ self.shape_rot
        centre = (link_rot * self.shape_pos[None, :, None, :]).sum(-1) + frames.translation[:, self.shape_link]
        return rot, centre

    def collision_signed_distance(self, frames: HandFrames, points: torch.Tensor, shape_ids: torch.Tensor | None = None) -> torch.Tensor:
        """Signed distance of (B, P, 3) object-frame points to the hand, positive inside.

        The maximum over the collision shapes (capsules: r - |x - clamp-to-segment(x)|;
        boxes: the negated box SDF). ``shape_ids`` restricts it to a subset of shapes.
        """
        rot, centre = self.shape_frames(frames)
        ids = torch.arange(len(self.shape_kind), device=self.device) if shape_ids is None else shape_ids
        rot, centre = rot[:, ids], centre[:, ids]
        rel = points[:, None, :, :] - centre[:, :, None, :]  # (B, S, P, 3)
        local = (rel[..., :, None] * rot[:, :, None, :, :]).sum(-2)  # R^T rel
        sd = shape_signed_distance(local, self.shape_kind[ids][None, :, None], self.shape_size[ids][None, :, None, :])
        return sd.max(dim=1).values


def shape_signed_distance(local: torch.Tensor, kind: torch.Tensor, size: torch.Tensor) -> torch.Tensor:
    """Signed distance (positive inside) of points in their shape's frame; capsules along z, boxes.

    ``local`` (..., 3); ``kind`` and ``size`` (..., ) and (..., 3) broadcast against it.
    """
    capsule_sd = capsule_signed_distance(local, size[..., 0], size[..., 1])
    return torch.where(kind == CAPSULE, capsule_sd, box_signed_distance(local, size))


def capsule_signed_distance(local: torch.Tensor, radius: torch.Tensor, half_length: torch.Tensor) -> torch.Tensor:
    """r − ‖x − clamp-to-axis-segment(x)‖ for points (..., 3) in the frame of a capsule along z."""
    z_clamped = torch.maximum(torch.minimum(local[..., 2], half_length), -half_length)
    axis_offset = torch.stack([local[..., 0], local[..., 1], local[..., 2] - z_clamped], dim=-1)
    return radius - (axis_offset.square().sum(-1) + 1e-18).sqrt()


def box_signed_distance(local: torch.Tensor, half_extent: torch.Tensor) -> torch.Tensor:
    """The negated box SDF for points (..., 3) in the frame of a box of half extents (..., 3)."""
    q = local.abs() - half_extent
    outside = (q.clamp(min=0).square().sum(-1) + 1e-18).sqrt()
    inside = q.max(dim=-1).values.clamp(max=0)
    return -(outside + inside)


def mujoco_geom(name: str):
    import mujoco

    return getattr(mujoco.mjtGeom, f"mjGEOM_{name.upper()}")


def _is_zero_length(hand: ShadowHand, a: int, b: int) -> bool:
    """Siblings hung at the same point (e.g. thumb base bodies) count as adjacent."""
    return bool(torch.allclose(hand._offset_pos[a], hand._offset_pos[b]))


def _shape_surface_samples(kind: int, size: list[float], count: int) -> np.ndarray:
    """Deterministic, roughly even points on a capsule (along z) or box surface, shape frame."""
    golden = math.pi * (3.0 - math.sqrt(5.0))
    if kind == CAPSULE:
        r, half = size[0], size[1]
        cyl_area, cap_area = 2 * math.pi * r * 2 * half, 4 * math.pi * r * r
        n_cyl = max(4, int(round(count * cyl_area / (cyl_area + cap_area))))
        n_cap = max(2, count - n_cyl)
        k = np.arange(n_cyl)
        z = -half + 2 * half * (k + 0.5) / n_cyl
        theta = k * golden
        cyl = np.stack([r * np.cos(theta), r * np.sin(theta), z], axis=1)
        k = np.arange(n_cap)
        cz = 1 - 2 * (k + 0.5) / n_cap
        rho = np.sqrt(1 - cz**2)
        sph = np.stack([r * rho * np.cos(k * golden), r * rho * np.sin(k * golden), r * cz], axis=1)
        sph[:, 2] += np.where(sph[:, 2] >= 0, half, -half)
        return np.concatenate([cyl, sph])
    half_extent = np.asarray(size[:3])
    areas = np.array([half_extent[1] * half_extent[2], half_extent[0] * half_extent[2], half_extent[0] * half_extent[1]]) * 2
    per_axis = np.maximum(1, np.round(count * areas / areas.sum() / 2)).astype(int)
    pts = []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        n = per_axis[axis]
        side = int(math.ceil(math.sqrt(n)))
        grid = (np.arange(side) + 0.5) / side * 2 - 1
        gu, gv = np.meshgrid(grid, grid, indexing="ij")
        for sign in (-1.0, 1.0):
            face = np.zeros((side * side, 3))
            face[:, axis] = sign * half_extent[axis]
            face[:, u] = gu.ravel() * half_extent[u]
            face[:, v] = gv.ravel() * half_extent[v]
            pts.append(face)
    return np.concatenate(pts)
