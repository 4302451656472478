"""Any hand read from its MJCF (``hand.description``) as the batched, differentiable hand model the energies use.

``DescribedHand(description)`` offers what ``ShadowHand`` offers the energies, the optimizer and the lift test
(link frames, collision shapes as capsules and boxes, contact candidates, self-penetration keypoints, surface
samples, joint limits), built from a ``HandDescription`` instead of the Shadow Hand's hand-written tables. It
subclasses ``ShadowHand`` only to reuse its kinematics (the tree walk in torch and the compiled kernel) and point-set
methods, which read nothing but the tensors built here; the Shadow Hand's own code path is untouched.

Pose: ``hand_pose`` = [t (3, m), static-xyz Euler (3, rad), the hand's J joints (rad) in qpos order], the pose of the
description's root link (``links[0]``, usually the palm) in the object frame, so its length is 6 + J (15 for the
tests' three-finger hand, 22 for Allegro and LEAP; the Shadow Hand's 28 when it is described). The root body's own
offset in the MJCF's world is dropped: the pose *is* the root frame.

Collision shapes: the energies know capsules and boxes (analytic signed distances, compiled kernels), so the MJCF's
geoms map to them: capsule and sphere (a capsule of half length 0) as they are; box as it is; a mesh geom as the box
``hand.description`` fitted to it; a cylinder and an ellipsoid as their bounding boxes (coarser, never smaller).
MuJoCo's lift test simulates the MJCF's own geoms.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import torch

from dexlite_pipeline.hand.derive import quat_to_matrix
from dexlite_pipeline.hand.description import HandDescription, hand_description
from dexlite_pipeline.hand.model import BOX, CAPSULE, ShadowHand
from dexlite_pipeline.hand.rotation import quat_wxyz_to_matrix

JOINTS_START = 6  # the joints follow the palm's translation (3) and Euler angles (3) in a stored pose
KEYPOINT_INSET_M = 0.01  # self-penetration keypoints start this far in from a shape's ends (as the Shadow Hand's)
KEYPOINT_SPACING_M = 0.012  # ... and are at most about this far apart along its axis or mid-plane
REST_CLEARANCE_M = 0.02  # keypoint pairs closer than this at the open pre-grasp are not counted (E_spen's default margin)
SQUEEZE_SPACING_STRIDE = 4  # surface samples kept for the lift test's squeeze: every 4th (~4 mm apart), ...
SQUEEZE_MIN_PER_SHAPE = 16  # ... at least this many per shape


def _energy_shape(shape) -> tuple[int, list[float], np.ndarray, np.ndarray]:
    """(kind, size [3], position (3,), rotation (3, 3)) in the link frame of one description shape as a capsule or box."""
    rot = quat_to_matrix(shape.quat)
    pos = np.asarray(shape.pos, dtype=np.float64)
    size = [float(v) for v in shape.size]
    if shape.kind == "capsule":
        return CAPSULE, [size[0], size[1], 0.0], pos, rot
    if shape.kind == "sphere":
        return CAPSULE, [size[0], 0.0, 0.0], pos, rot
    if shape.kind == "box":
        return BOX, size, pos, rot
    if shape.kind == "cylinder":
        return BOX, [size[0], size[0], size[1]], pos, rot
    if shape.kind == "ellipsoid":
        return BOX, size, pos, rot
    if shape.kind == "mesh":
        return BOX, [float(v) for v in shape.box_half], pos + rot @ np.asarray(shape.box_centre, dtype=np.float64), rot
    raise ValueError(f"collision shape {shape.name}: kind {shape.kind} has no capsule or box form")


def _line(half: float) -> np.ndarray:
    """Positions along an axis of half length ``half``: ``KEYPOINT_INSET_M`` in from the ends, ~``KEYPOINT_SPACING_M`` apart."""
    low, high = -half + KEYPOINT_INSET_M, half - KEYPOINT_INSET_M
    if high <= low:
        return np.zeros(1)
    return np.linspace(low, high, max(1, int(round((high - low) / KEYPOINT_SPACING_M)) + 1))


def _shape_keypoints(kind: int, size: list[float]) -> np.ndarray:
    """Self-penetration keypoints in the shape frame: along a capsule's axis, on a grid in a box's mid-plane (thinnest axis)."""
    if kind == CAPSULE:
        z = _line(size[1])
        return np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=1)
    half = np.asarray(size[:3])
    thin = int(np.argmin(half))
    u, v = (a for a in range(3) if a != thin)
    gu, gv = np.meshgrid(_line(half[u]), _line(half[v]), indexing="ij")
    points = np.zeros((gu.size, 3))
    points[:, u], points[:, v] = gu.ravel(), gv.ravel()
    return points


class DescribedHand(ShadowHand):
    """A hand from its ``HandDescription``, with ``ShadowHand``'s interface; ``pose_dim`` = 6 + its joint count."""

    def __init__(self, description: HandDescription | str, device: torch.device | str = "cpu", dtype: torch.dtype = torch.float32) -> None:
        if not isinstance(description, HandDescription):
            description = hand_description(description)
        self.description = description
        self.device = torch.device(device)
        self.dtype = dtype
        model = description.mj_model()
        self._mj_model = model
        self.link_names = tuple(description.links)
        self.link_index = {name: i for i, name in enumerate(self.link_names)}
        self.joint_names = tuple(description.joint_names)
        self.pose_dim = JOINTS_START + len(self.joint_names)
        self.joint_limits = torch.tensor(description.joint_limits, dtype=dtype, device=self.device)  # (J, 2)
        self.root_link = self.link_names[0]

        self._parent = list(description.parents)
        body_joint = np.full(len(self.link_names), -1)
        for j in range(model.njnt):
            body_joint[model.jnt_bodyid[j] - 1] = j
        self._body_joint = body_joint.tolist()
        offset_pos = model.body_pos[1:].copy()
        offset_quat = model.body_quat[1:].copy()
        offset_pos[0], offset_quat[0] = 0.0, (1.0, 0.0, 0.0, 0.0)  # the pose is the root link's frame
        as_t = functools.partial(torch.as_tensor, dtype=dtype, device=self.device)
        self._offset_pos = as_t(offset_pos)
        self._offset_rot = quat_wxyz_to_matrix(as_t(offset_quat))
        self._offset_is_identity = [bool(np.allclose(q, [1, 0, 0, 0])) for q in offset_quat]
        self._joint_axis = as_t(model.jnt_axis.copy())
        self._joint_pos = as_t(model.jnt_pos.copy())
        if np.abs(model.jnt_pos).max() > 0:
            raise ValueError(f"hand {description.name}: joint anchors off the body origin are not supported")
        self._build_levels()
        self._kinematics = None

        self._build_described_shapes(as_t)
        self._build_described_points(as_t)
        # Fingers as link and joint index tuples (the lift test's squeeze moves each finger's joints on its own).
        self.finger_links = tuple(tuple(self.link_index[name] for name in finger) for finger in description.fingers)
        joint_link = [self.link_index[j.link] for j in description.joints]
        self.finger_joints = tuple(tuple(j for j, link in enumerate(joint_link) if link in finger) for finger in self.finger_links)
        self.palm_frame_local = np.asarray(description.palm_frame, dtype=np.float64)  # (4, 4) in the root link's frame

    # ----------------------------------------------------------------- geometry
    def _build_described_shapes(self, as_t) -> None:
        kinds, links, pos, rot, size = [], [], [], [], []
        for shape in self.description.shapes:
            kind, shape_size, shape_pos, shape_rot = _energy_shape(shape)
            kinds.append(kind)
            links.append(self.link_index[shape.link])
            pos.append(shape_pos)
            rot.append(shape_rot)
            size.append(shape_size)
        self._set_shapes(kinds, links, as_t(np.array(pos)), as_t(np.array(rot)), as_t(np.array(size)))

    def _build_described_points(self, as_t) -> None:
        d = self.description
        self.contact_points_local = as_t(np.asarray(d.contact_points))
        self.contact_link = torch.as_tensor(np.asarray(d.contact_link), dtype=torch.long, device=self.device)
        self.side_contact_points_local = as_t(np.zeros((0, 3)))  # no side candidates (lateral grasps: the Shadow Hand only)
        self.side_contact_link = torch.zeros(0, dtype=torch.long, device=self.device)
        self.tip_contact_points_local = as_t(np.zeros((0, 3)))  # no thumb-tip candidates (precision types: the Shadow Hand only)
        self.tip_contact_link = torch.zeros(0, dtype=torch.long, device=self.device)

        pts, ids = [], []
        rots, poss = self.shape_rot.cpu().double().numpy(), self.shape_pos.cpu().double().numpy()
        for s in range(len(self.shape_kind)):
            local = _shape_keypoints(int(self.shape_kind[s]), self.shape_size[s].tolist())
            pts.append(local @ rots[s].T + poss[s])
            ids += [int(self.shape_link[s])] * len(local)
        self.keypoints_local = as_t(np.concatenate(pts))
        self.keypoint_link = torch.tensor(ids, device=self.device)
        self.keypoint_pair_mask = self._keypoint_pair_mask()

        pts, ids = [], []
        for shape in d.shapes:
            stride = max(1, min(SQUEEZE_SPACING_STRIDE, len(shape.points) // SQUEEZE_MIN_PER_SHAPE))
            kept = shape.points[::stride]
            pts.append(kept)
            ids += [self.link_index[shape.link]] * len(kept)
        self.surface_points_local = as_t(np.concatenate(pts))
        self.surface_link = torch.tensor(ids, device=self.device)

    def _rigid_group(self) -> list[int]:
        """Each link's rigid body: itself when a joint turns it (or it is the root), else its parent's group."""
        group: list[int] = []
        for link, parent in enumerate(self._parent):
            group.append(link if parent < 0 or self._body_joint[link] >= 0 else group[parent])
        return group

    def _keypoint_pair_mask(self) -> torch.Tensor:
        """Pairs counted by E_spen: keypoints on links that are not rigidly joined, parent and child, or siblings hung
        at one point (a fixed body, e.g. Allegro's fingertip under its distal link, counts as its parent), and that lie
        ``REST_CLEARANCE_M`` apart or more at the open pre-grasp: a pair closer than that in the open hand is where the
        hand is built close (LEAP's neighbouring fingers, 1.3 cm apart at their side plates; Allegro's thumb base at the
        palm), not a self-penetration, and would only push the open hand apart."""
        group = self._rigid_group()
        link = [group[k] for k in self.keypoint_link.tolist()]
        parent = [group[p] if p >= 0 else -1 for p in self._parent]
        offsets = self._offset_pos.cpu().double()
        n = len(link)
        mask = torch.zeros(n, n, dtype=torch.bool, device=self.device)
        for i in range(n):
            for j in range(i + 1, n):
                a, b = link[i], link[j]
                siblings = parent[a] == parent[b] and parent[a] >= 0 and bool(torch.allclose(offsets[a], offsets[b]))
                adjacent = a == b or parent[a] == b or parent[b] == a or siblings
                mask[i, j] = mask[j, i] = not adjacent
        joints = torch.as_tensor(self.description.pregrasp, dtype=self.dtype, device=self.device)[None]
        frames = self.forward_parts_torch(torch.eye(3, dtype=self.dtype, device=self.device)[None], joints.new_zeros(1, 3), joints)
        rest = self.penetration_keypoints(frames)[0].double()
        return mask & (torch.cdist(rest, rest) >= REST_CLEARANCE_M)

    # --------------------------------------------------------------- kinematics
    def forward(self, hand_pose: torch.Tensor):
        """All link frames in the object frame for a (B, 6 + J) batch of hand poses."""
        palm_rot, palm_t = self.palm_frame(hand_pose)
        return self.forward_parts(palm_rot, palm_t, hand_pose[..., JOINTS_START:])

    # ------------------------------------------------------------ pre-grasp data
    def approach_local(self, tilt_deg: float) -> np.ndarray:
        """(3,) the direction the palm moves along to reach an object, root frame: the palm normal (palm frame z)
        tilted ``tilt_deg`` toward the fingers (palm frame x), as the Shadow Hand's start tilts its palmar normal."""
        z, x = self.palm_frame_local[:3, 2], self.palm_frame_local[:3, 0]
        return math.cos(math.radians(tilt_deg)) * z + math.sin(math.radians(tilt_deg)) * x

    def opposing_candidates(self) -> tuple[int, ...]:
        """Contact-table indices of the candidates on the opposing fingers' links (the thumb's; ``HandDescription.opposing``
        names each such finger by its leaf link). Empty when no finger opposes the others."""
        leaves = set(self.description.opposing)
        links = {self.link_index[name] for finger in self.description.fingers if finger[-1] in leaves for name in finger}
        return tuple(i for i, link in enumerate(self.contact_link.tolist()) if link in links)

    def pregrasp_joints(self) -> torch.Tensor:
        """(J,) the description's open pre-grasp (rad), in the hand's dtype."""
        return torch.as_tensor(self.description.pregrasp, dtype=self.dtype)


def is_described(hand) -> bool:
    """True for a ``DescribedHand`` (any hand from its MJCF), False for the built-in ``ShadowHand``."""
    return isinstance(hand, DescribedHand)


__all__ = ["JOINTS_START", "DescribedHand", "is_described"]
