"""The five grasp energy terms, one small class each (DexGraspNet's definitions, DESIGN.md).

Each term only computes its value per grasp, (B,) in SI units (metres for distances);
weighting is held apart (``energy.grasp_energy.EnergyWeights``), so the seed optimizer,
post-optimization and the CVAE's training loss share the same terms with their own weights.
All terms are differentiable in the points and frames they receive.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from dexlite_pipeline.hand.model import HandFrames, ShadowHand, shape_signed_distance
from dexlite_pipeline.energy.link_map import LinkFrameMap
from dexlite_pipeline.energy.spheres import build_hand_spheres
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
        self.keypoint_map = LinkFrameMap.for_points(hand.keypoints_local, hand.keypoint_link, len(hand.link_names))

    def __call__(self, frames: HandFrames) -> torch.Tensor:
        return self.penalty(self.keypoint_map(frames), self.pairs, self.margin_m)

    @staticmethod
    def penalty(keypoints: torch.Tensor, pairs: tuple[torch.Tensor, torch.Tensor], margin_m: float) -> torch.Tensor:
        """Σ over the listed pairs (i, j) of max(0, margin − ‖p_i − p_j‖) for keypoints (B, K, 3)."""
        diff = keypoints[:, pairs[0]] - keypoints[:, pairs[1]]
        distance = (diff.square().sum(-1) + 1e-18).sqrt()
        return torch.relu(margin_m - distance).sum(dim=-1)


@dataclass
class PenetrationResult:
    """E_pen per grasp and the deepest penetration each way (metres, detached)."""

    energy: torch.Tensor
    object_in_hand_max_m: torch.Tensor
    hand_in_object_max_m: torch.Tensor


class PenetrationTerm:
    """E_pen: depth of object surface points inside the hand, plus depth of buried hand spheres' centres.

    Object points in the hand's capsules and boxes is DexGraspNet's E_pen (its 1 mm
    threshold applies to it). It is capped by a link's radius and blind to a link buried
    wholly inside the object, so the hand's sphere model adds Σ max(0, d(c)) over sphere
    centres c: zero until a link is in deeper than its radius, which is exactly where the
    first part stops seeing it, so the two never count the same penetration twice.
    ``hand_in_object_max_m`` is the full depth max(d(c) + r) (for ``penetration_mm``).

    Exact culling keeps it cheap. Every sphere's depth is found first without autograd; a
    shape can hold object points only if one of its spheres reaches the object within the
    shape's covering gap plus the grid's interpolation error bound (see ``interpolation_error``),
    so all other shapes are skipped, and an object point farther from a shape's centre
    than its bounding radius is never tested. Only the spheres and points actually inside
    are re-evaluated with gradients, so backward stays small.
    """

    def __init__(self, hand: ShadowHand, sdf_bank: SdfBank, object_points: torch.Tensor) -> None:
        self.hand = hand
        self.bank = sdf_bank
        self.object_points = object_points  # (n_objects, P, 3), normalized frame
        # [p, |p|²] per point: squared distances to centres c are then one product with [−2c, 1].
        self.object_points_aug = torch.cat([object_points, object_points.square().sum(-1, keepdim=True)], dim=-1)
        self.radius = hand.shape_bounding_radius
        self.interpolation_error = sdf_bank.voxel_size * 3**0.5 / 2  # normalized units, per object
        # Trilinear interpolation of an exact SDF f (1-Lipschitz) errs by at most
        # Σ wᵢ|cᵢ − x| ≤ (Σ wᵢ|cᵢ − x|²)^½ = h·(Σ_axes t(1−t))^½ ≤ h·√3/2 (t: fractional coordinate).
        self.spheres = build_hand_spheres(hand)
        link_count = len(hand.link_names)
        self.sphere_map = LinkFrameMap.for_points(self.spheres.centre_local, self.spheres.link, link_count)
        self.shape_map = LinkFrameMap.for_frames(hand.shape_rot, hand.shape_pos, hand.shape_link, link_count)

    def __call__(self, frames: HandFrames, object_index: torch.Tensor, scale: torch.Tensor) -> PenetrationResult:
        batch = object_index.shape[0]
        radius = self.spheres.radius
        centre = self.sphere_map(frames)  # (B, K, 3)
        with torch.no_grad():
            distance, _ = self.bank.signed_distance(centre.detach(), object_index[:, None], scale[:, None], with_normal=False)
            sphere_depth = distance + radius
            shape_reach = sphere_depth.new_full((batch, len(self.radius)), -torch.inf)
            shape_reach = shape_reach.scatter_reduce(1, self.spheres.shape.expand(batch, -1), sphere_depth, "amax")
            margin = (self.interpolation_error[object_index] * scale)[:, None] + self.spheres.shape_gap[None, :]
            active = shape_reach > -margin
        b, k = (sphere_depth > radius).nonzero(as_tuple=True)  # centres inside the object
        distance, _ = self.bank.signed_distance(centre[b, k], object_index[b], scale[b], with_normal=False)
        hand_energy = distance.new_zeros(batch).index_add(0, b, distance)
        hand_max = sphere_depth.max(dim=1).values.clamp(min=0)
        obj_energy, obj_max = self._object_in_hand(self.shape_map(frames), active, object_index, scale)
        return PenetrationResult(obj_energy + hand_energy, obj_max, hand_max)

    def _object_in_hand(self, shape_frames, active, object_index, scale):
        """Σ over object points of their depth inside the active shapes (deepest shape per point)."""
        batch = shape_frames.shape[0]
        point_count = self.object_points.shape[1]
        pair_b, pair_s = active.nonzero(as_tuple=True)
        frame = shape_frames[pair_b, pair_s]  # (A, 3, 4): [R | c]
        rot_t = frame[:, :, :3].transpose(1, 2)
        # Affine map from the normalized object frame to each pair's shape frame: Rᵀ (s·p − c).
        to_local = torch.cat([rot_t * scale[pair_b, None, None], -(rot_t @ frame[:, :, 3:])], dim=2)
        cand_pair, cand_point, points = self._candidates_near_shapes(frame[:, :, 3].detach(), pair_b, pair_s, object_index, scale)
        with torch.no_grad():
            depth = self._depth_in_shape(to_local.detach()[cand_pair], points, pair_s[cand_pair])
            inside = depth > 0
        cand_pair, cand_point, points = cand_pair[inside], cand_point[inside], points[inside]
        depth = self._depth_in_shape(to_local[cand_pair], points, pair_s[cand_pair])
        # A point inside several shapes counts once, at its deepest.
        key = pair_b[cand_pair] * point_count + cand_point
        per_point = depth.new_zeros(batch * point_count).scatter_reduce(0, key, depth, "amax").reshape(batch, point_count)
        return per_point.sum(-1), per_point.detach().max(-1).values

    def _candidates_near_shapes(self, centre, pair_b, pair_s, object_index, scale):
        """(pair, point index, point) of object points within each active shape's bounding radius."""
        pairs, indices = [], []
        pair_object = object_index[pair_b]
        for obj in torch.unique(pair_object).tolist():
            sel = (pair_object == obj).nonzero(as_tuple=True)[0]
            pair_scale = scale[pair_b[sel]]
            c = centre[sel] / pair_scale[:, None]
            reach = self.radius[pair_s[sel]] / pair_scale
            c_aug = torch.cat([-2 * c, torch.ones_like(c[:, :1])], dim=1)
            near = (c_aug @ self.object_points_aug[obj].T) < (reach.square() - c.square().sum(-1))[:, None]
            local_pair, point = near.nonzero(as_tuple=True)
            pairs.append(sel[local_pair])
            indices.append(point)
        pair = torch.cat(pairs) if pairs else torch.zeros(0, dtype=torch.long, device=centre.device)
        point = torch.cat(indices) if indices else pair
        return pair, point, self.object_points[object_index[pair_b[pair]], point]

    def _depth_in_shape(self, to_local, points, shape):
        local = (to_local[:, :, :3] * points[:, None, :]).sum(-1) + to_local[:, :, 3]
        return shape_signed_distance(local, self.hand.shape_kind[shape], self.hand.shape_size[shape])
