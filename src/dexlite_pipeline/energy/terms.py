"""The five grasp energy terms, one small class each (DexGraspNet's definitions, DESIGN.md).

Each term only computes its value per grasp, (B,) in SI units (metres for distances);
weighting is held apart (``energy.grasp_energy.EnergyWeights``), so the seed optimizer,
post-optimization and the CVAE's training loss share the same terms with their own weights.
All terms are differentiable in the points and frames they receive.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from dexlite_pipeline.hand.model import CAPSULE, HandFrames, ShadowHand
from dexlite_pipeline.objects.assets import SdfBank


class ForceClosureTerm:
    """E_fc = ‖Σ n_i‖² + ‖Σ x_i × n_i‖²: the net wrench of unit contact normals (‖nᵀG‖²)."""

    def __call__(self, contact_points: torch.Tensor, contact_normals: torch.Tensor) -> torch.Tensor:
        force = contact_normals.sum(dim=1)
        torque = torch.cross(contact_points, contact_normals, dim=-1).sum(dim=1)
        return force.square().sum(-1) + torque.square().sum(-1)


class ContactDistanceTerm:
    """E_dis = Σ |d(x_i)|: contacts should lie on the object surface."""

    def __call__(self, contact_signed_distance: torch.Tensor) -> torch.Tensor:
        return contact_signed_distance.abs().sum(dim=1)


class JointLimitTerm:
    """E_joints = Σ max(0, q − q⁺) + max(0, q⁻ − q)."""

    def __init__(self, joint_limits: torch.Tensor) -> None:
        self.lower = joint_limits[:, 0]
        self.upper = joint_limits[:, 1]

    def __call__(self, joints: torch.Tensor) -> torch.Tensor:
        return (torch.relu(joints - self.upper) + torch.relu(self.lower - joints)).sum(dim=-1)


class SelfPenetrationTerm:
    """E_spen = Σ over keypoint pairs on different, non-adjacent links of max(0, margin − ‖p_i − p_j‖).

    Each unordered pair counts once (DexGraspNet sums the full symmetric matrix, i.e. twice).
    """

    def __init__(self, hand: ShadowHand, margin_m: float = 0.02) -> None:
        self.hand = hand
        self.margin_m = margin_m
        self.pairs = torch.triu(hand.keypoint_pair_mask, diagonal=1).nonzero(as_tuple=True)

    def __call__(self, frames: HandFrames) -> torch.Tensor:
        keypoints = self.hand.penetration_keypoints(frames)
        diff = keypoints[:, self.pairs[0]] - keypoints[:, self.pairs[1]]
        distance = (diff.square().sum(-1) + 1e-12).sqrt()
        return torch.relu(self.margin_m - distance).sum(dim=-1)


@dataclass
class PenetrationResult:
    """E_pen per grasp and the deepest penetration each way (metres, detached)."""

    energy: torch.Tensor
    object_in_hand_max_m: torch.Tensor
    hand_in_object_max_m: torch.Tensor


def shape_signed_distance(local: torch.Tensor, kind: torch.Tensor, size: torch.Tensor) -> torch.Tensor:
    """Signed distance (positive inside) of points in their shape's frame; capsules along z, boxes.

    ``local`` (..., 3); ``kind`` and ``size`` (..., ) and (..., 3) broadcast against it.
    """
    half = size[..., 1]
    z_clamped = torch.maximum(torch.minimum(local[..., 2], half), -half)
    axis_offset = torch.stack([local[..., 0], local[..., 1], local[..., 2] - z_clamped], dim=-1)
    capsule_sd = size[..., 0] - (axis_offset.square().sum(-1) + 1e-12).sqrt()
    q = local.abs() - size
    outside = (q.clamp(min=0).square().sum(-1) + 1e-12).sqrt()
    inside = q.max(dim=-1).values.clamp(max=0)
    box_sd = -(outside + inside)
    return torch.where(kind == CAPSULE, capsule_sd, box_sd)


class PenetrationTerm:
    """E_pen: depth of object surface points inside the hand plus depth of hand surface points inside the object.

    Object points in the hand's capsules and boxes is DexGraspNet's E_pen; it is capped by
    a link's radius and blind to a link buried wholly inside the object, so the hand's
    surface points against the object's SDF are added (DESIGN.md, "penetration").

    Exact culling keeps it cheap: a shape whose centre is farther from the object than
    its bounding radius (plus one voxel diagonal for the grid's interpolation error)
    cannot touch it and is skipped; an object point farther from a shape's centre than
    that radius cannot be inside it. Depths are found without autograd, and only the
    points actually inside are re-evaluated with gradients, so backward stays small.
    """

    def __init__(self, hand: ShadowHand, sdf_bank: SdfBank, object_points: torch.Tensor) -> None:
        self.hand = hand
        self.bank = sdf_bank
        self.object_points = object_points  # (n_objects, P, 3), normalized frame
        self.radius = hand.shape_bounding_radius
        self.voxel_diagonal = sdf_bank.voxel_size * 3**0.5  # normalized units, per object
        link_count = len(hand.link_names)
        self.shape_to_link = torch.nn.functional.one_hot(hand.shape_link, link_count).to(hand.dtype)  # (S, L)

    def active_shapes(self, shape_centre: torch.Tensor, object_index: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
        """(B, S) bool: shapes that may touch the object (exact test, see class doc)."""
        with torch.no_grad():
            centre_depth, _ = self.bank.signed_distance(shape_centre, object_index, scale)
            margin = (self.voxel_diagonal[object_index] * scale)[:, None]
            return -centre_depth < self.radius[None, :] + margin

    def __call__(self, frames: HandFrames, object_index: torch.Tensor, scale: torch.Tensor) -> PenetrationResult:
        shape_rot, shape_centre = self.hand.shape_frames(frames)
        active = self.active_shapes(shape_centre.detach(), object_index, scale)
        obj_energy, obj_max = self._object_in_hand(shape_rot, shape_centre, active, object_index, scale)
        hand_energy, hand_max = self._hand_in_object(frames, active, object_index, scale)
        return PenetrationResult(obj_energy + hand_energy, obj_max, hand_max)

    def _object_in_hand(self, shape_rot, shape_centre, active, object_index, scale):
        batch = shape_centre.shape[0]
        point_count = self.object_points.shape[1]
        pair_b, pair_s = active.nonzero(as_tuple=True)
        cand_pair, cand_point = self._candidates_near_shapes(shape_centre.detach(), pair_b, pair_s, object_index, scale)
        b, s = pair_b[cand_pair], pair_s[cand_pair]
        points = self.object_points[object_index[b], cand_point] * scale[b, None]
        with torch.no_grad():
            depth = self._depth_in_shape(points, shape_rot.detach()[b, s], shape_centre.detach()[b, s], s)
            inside = depth > 0
        b, s, points, cand_point = b[inside], s[inside], points[inside], cand_point[inside]
        depth = self._depth_in_shape(points, shape_rot[b, s], shape_centre[b, s], s)
        # A point inside several shapes counts once, at its deepest.
        per_point = depth.new_zeros(batch * point_count).scatter_reduce(0, b * point_count + cand_point, depth, "amax")
        per_point = per_point.reshape(batch, point_count)
        return per_point.sum(-1), per_point.detach().max(-1).values

    def _candidates_near_shapes(self, centre, pair_b, pair_s, object_index, scale):
        """(pair, point) index lists of object points within each active shape's bounding radius."""
        pairs, points = [], []
        pair_object = object_index[pair_b]
        for obj in torch.unique(pair_object).tolist():
            sel = (pair_object == obj).nonzero(as_tuple=True)[0]
            pair_scale = scale[pair_b[sel]]
            centre_normalized = centre[pair_b[sel], pair_s[sel]] / pair_scale[:, None]
            reach = (self.radius[pair_s[sel]] / pair_scale)[:, None]
            near = torch.cdist(centre_normalized, self.object_points[obj]) < reach
            local_pair, point = near.nonzero(as_tuple=True)
            pairs.append(sel[local_pair])
            points.append(point)
        if not pairs:
            empty = torch.zeros(0, dtype=torch.long, device=centre.device)
            return empty, empty
        return torch.cat(pairs), torch.cat(points)

    def _depth_in_shape(self, points, rot, centre, shape):
        local = ((points - centre)[..., :, None] * rot).sum(-2)  # Rᵀ (x − c)
        return shape_signed_distance(local, self.hand.shape_kind[shape], self.hand.shape_size[shape])

    def _hand_in_object(self, frames, active, object_index, scale):
        batch = active.shape[0]
        link_active = (active.to(self.shape_to_link.dtype) @ self.shape_to_link) > 0
        b, i = link_active[:, self.hand.surface_link].nonzero(as_tuple=True)
        with torch.no_grad():
            depth = self._surface_point_depth(frames.rotation.detach(), frames.translation.detach(), b, i, object_index, scale)
            inside = depth > 0
        max_depth = depth.new_zeros(batch).scatter_reduce(0, b[inside], depth[inside], "amax")
        b, i = b[inside], i[inside]
        depth = self._surface_point_depth(frames.rotation, frames.translation, b, i, object_index, scale)
        energy = depth.new_zeros(batch).index_add(0, b, depth)
        return energy, max_depth

    def _surface_point_depth(self, rotation, translation, b, i, object_index, scale):
        link = self.hand.surface_link[i]
        points = (rotation[b, link] * self.hand.surface_points_local[i][:, None, :]).sum(-1) + translation[b, link]
        depth, _ = self.bank.signed_distance(points[:, None, :], object_index[b], scale[b])
        return depth[:, 0]
