"""The five grasp energy terms, one small class each (DexGraspNet's definitions; docs/design.md), and E_table.

Each term is an ``EnergyTerm``: it carries its result name (``name``, e.g. "E_fc"), the
field of ``EnergyWeights`` that weights it (``weight_key``, e.g. "fc"), and
``evaluate(context)``, its value per grasp, (B,) in SI units (metres for distances,
radians for joint angles), read from the ``EnergyContext`` that ``GraspEnergy`` builds once
per evaluation (link frames, joints, contact points with their signed distances and
normals, the penetration result). E_pen, the largest, is ``energy.penetration_term``. ``GraspEnergy`` sums weight·value over its list of terms,
so a new term is one subclass here plus one entry in that list. Weighting is held apart
from the terms, so the from-scratch optimizer, post-optimization and the CVAE's training loss share
the same terms with their own weights. All terms are differentiable in the points and
frames they receive. Each class is also callable on its own inputs (``__call__``), for
callers that have those without a context (``GraspEnergy.best_contacts``, tests).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import torch

from dexlite_pipeline.energy.link_map import LinkFrameMap
from dexlite_pipeline.hand.model import HandFrames, ShadowHand


@dataclass
class PenetrationResult:
    """E_pen per grasp and the deepest penetration each way (metres, detached, ≥ 0)."""

    energy: torch.Tensor
    object_in_hand_max_m: torch.Tensor
    hand_in_object_max_m: torch.Tensor

    @property
    def depth_m(self) -> torch.Tensor:
        """(B,) the grasp's penetration depth: the deeper of the two directions (metres)."""
        return torch.maximum(self.object_in_hand_max_m, self.hand_in_object_max_m)


@dataclass
class EnergyContext:
    """What the terms of one evaluation share, computed once per batch of B grasps.

    Positions are in the object frame, in metres (the object scaled by ``scale``).
    """

    frames: HandFrames  # link rotations (B, L, 3, 3) and translations (B, L, 3)
    joints: torch.Tensor  # (B, 22) joint angles, radians
    object_index: torch.Tensor  # (B,) bank index of each grasp's object
    scale: torch.Tensor  # (B,) metres per normalized object unit
    contact_index: torch.Tensor  # (B, 4) chosen contact candidates
    contact_points: torch.Tensor  # (B, 4, 3) positions of the chosen candidates
    contact_distance: torch.Tensor  # (B, 4) their signed distances to the surface (positive outside)
    contact_normal: torch.Tensor  # (B, 4, 3) unit surface normals at them
    penetration: PenetrationResult  # E_pen and the deepest penetration each way
    support_normal: torch.Tensor | None = None  # (B, 3) table's upward normal (tabletop mode; None: floating)
    support_offset_m: torch.Tensor | None = None  # (B,) table height term: n·x + offset ≥ 0 above the table
    judged_depth_m: torch.Tensor | None = None  # (B,) the judged penetration depth, when asked for (``GraspEnergy.judge``)


class EnergyTerm:
    """One named term of the grasp energy; ``GraspEnergy`` adds weight·``evaluate(context)``."""

    name: ClassVar[str]  # key in ``EnergyResult.terms`` (and in stored arrays)
    weight_key: ClassVar[str]  # field of ``EnergyWeights`` holding its weight

    def evaluate(self, context: EnergyContext) -> torch.Tensor:
        """The term per grasp, (B,), differentiable in the context's frames, joints and points."""
        raise NotImplementedError


class ForceClosureTerm(EnergyTerm):
    """E_fc = ‖Σ n_i‖² + ‖Σ x_i × n_i‖²: the net wrench of unit contact normals (‖nᵀG‖²)."""

    name = "E_fc"
    weight_key = "fc"

    def evaluate(self, context: EnergyContext) -> torch.Tensor:
        return self(context.contact_points, context.contact_normal)

    def __call__(self, contact_points: torch.Tensor, contact_normals: torch.Tensor) -> torch.Tensor:
        force = contact_normals.sum(dim=1)
        torque = torch.cross(contact_points, contact_normals, dim=-1).sum(dim=1)
        return force.square().sum(-1) + torque.square().sum(-1)


class ContactDistanceTerm(EnergyTerm):
    """E_dis = Σ |d(x_i)| (metres): contacts should lie on the object surface."""

    name = "E_dis"
    weight_key = "dis"

    def evaluate(self, context: EnergyContext) -> torch.Tensor:
        return self(context.contact_distance)

    def __call__(self, contact_signed_distance: torch.Tensor) -> torch.Tensor:
        return contact_signed_distance.abs().sum(dim=1)


class JointLimitTerm(EnergyTerm):
    """E_joints = Σ max(0, q − q⁺) + max(0, q⁻ − q) (radians) over the 22 joints."""

    name = "E_joints"
    weight_key = "joints"

    def __init__(self, joint_limits: torch.Tensor) -> None:
        self.lower = joint_limits[:, 0]
        self.upper = joint_limits[:, 1]

    def evaluate(self, context: EnergyContext) -> torch.Tensor:
        return self(context.joints)

    def __call__(self, joints: torch.Tensor) -> torch.Tensor:
        return (torch.relu(joints - self.upper) + torch.relu(self.lower - joints)).sum(dim=-1)


class SelfPenetrationTerm(EnergyTerm):
    """E_spen = Σ over keypoint pairs on different, non-adjacent links of max(0, margin − ‖p_i − p_j‖) (metres).

    Each unordered pair counts once (DexGraspNet sums the full symmetric matrix, i.e. twice).
    All pair distances are found without autograd; only the pairs closer than the margin
    (the only ones with a nonzero value or gradient) are evaluated again with gradients.
    """

    name = "E_spen"
    weight_key = "spen"

    def __init__(self, hand: ShadowHand, margin_m: float = 0.02) -> None:
        self.hand = hand
        self.margin_m = margin_m
        self.pairs = torch.triu(hand.keypoint_pair_mask, diagonal=1).nonzero(as_tuple=True)
        self.keypoint_map = LinkFrameMap.for_points(hand.keypoints_local, hand.keypoint_link, len(hand.link_names))
        self._kernel = None  # ``SelfPenetrationKernel``, built on the first CPU call

    def evaluate(self, context: EnergyContext) -> torch.Tensor:
        return self(context.frames)

    def __call__(self, frames: HandFrames) -> torch.Tensor:
        """(B,) E_spen; on the CPU compiled (``energy.self_penetration_kernel``), elsewhere ``evaluate_with_torch``."""
        if frames.translation.device.type == "cpu":
            if self._kernel is None:
                from dexlite_pipeline.energy.self_penetration_kernel import SelfPenetrationKernel  # imports numba: only when used

                self._kernel = SelfPenetrationKernel(self.hand.keypoints_local, self.hand.keypoint_link, *self.pairs, self.margin_m)
            return self._kernel(frames)
        return self.evaluate_with_torch(frames)

    def evaluate_with_torch(self, frames: HandFrames) -> torch.Tensor:
        """``__call__`` as torch operations, on any device."""
        first, second = self.pairs
        with torch.no_grad():
            keypoints = self.keypoint_map.transposed(frames)  # (K, 3, B)
            diff = keypoints.index_select(0, first) - keypoints.index_select(0, second)
            pair, grasp = ((diff.square().sum(1) + 1e-18).sqrt() < self.margin_m).nonzero(as_tuple=True)
        rows = self.keypoint_map.rows
        penalty = self.pair_penalty(rows(frames, grasp, first[pair]), rows(frames, grasp, second[pair]), self.margin_m)
        return penalty.new_zeros(frames.translation.shape[0]).index_add(0, grasp, penalty)

    @staticmethod
    def pair_penalty(first: torch.Tensor, second: torch.Tensor, margin_m: float) -> torch.Tensor:
        """max(0, margin − ‖p − q‖) for each pair of points p, q (..., 3)."""
        distance = ((first - second).square().sum(-1) + 1e-18).sqrt()
        return torch.relu(margin_m - distance)


class TableTerm(EnergyTerm):
    """E_table = Σ over the hand's collision shapes of how far their lowest point lies below the table (metres).

    Tabletop mode only (``scene.table``): the table is the plane n·x + offset = 0 of the object's
    resting pose (``tabletop``); each capsule's and box's lowest point is exact
    (``energy.table_clearance.HandTableClearance``), so a hand wholly above the table costs exactly 0.
    """

    name = "E_table"
    weight_key = "table"

    def __init__(self, hand: ShadowHand) -> None:
        from dexlite_pipeline.energy.table_clearance import HandTableClearance

        self.hand = hand
        self.clearance = HandTableClearance(hand)
        self._kernel = None  # ``TableKernel``, built on the first CPU call

    def evaluate(self, context: EnergyContext) -> torch.Tensor:
        return self(context.frames, context.support_normal, context.support_offset_m)

    def __call__(self, frames: HandFrames, normal: torch.Tensor, offset_m: torch.Tensor) -> torch.Tensor:
        """(B,) E_table; on the CPU compiled (``energy.table_kernel``), elsewhere ``evaluate_with_torch``."""
        if frames.translation.device.type == "cpu":
            if self._kernel is None:
                from dexlite_pipeline.energy.table_kernel import TableKernel  # imports numba: only when used

                self._kernel = TableKernel(self.hand, self.clearance.half_extent, self.clearance.radius)
            return self._kernel(frames, normal, offset_m)
        return self.evaluate_with_torch(frames, normal, offset_m)

    def evaluate_with_torch(self, frames: HandFrames, normal: torch.Tensor, offset_m: torch.Tensor) -> torch.Tensor:
        """``__call__`` as torch operations, on any device."""
        return torch.relu(-self.clearance.lowest_heights(frames, normal, offset_m)).sum(dim=1)
