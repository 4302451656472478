"""Squeeze targets of the lift test (step 2 of the protocol in ``sim.lift``), from the object's SDF in torch.

A grasp's fingers close from the grasp pose toward joint targets a little past it: each finger
that touches the object moves along the gradient that pushes its touching links into it.
Distances in metres, joint angles in radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from dexlite_pipeline.hand.described import is_described
from dexlite_pipeline.hand.model import JOINT_NAMES, JOINTS, ShadowHand
from dexlite_pipeline.objects.assets import SdfBank
from dexlite_pipeline.sim.config import LiftConfig

FINGERS = ("ff", "mf", "rf", "lf", "th")  # the Shadow Hand's; a hand from its MJCF has its description's fingers
JOINT_COLUMNS = slice(JOINTS.start, None)  # a stored pose's joints: the Shadow Hand's 22, a hand from its MJCF's J


def _finger_masks(hand: ShadowHand) -> tuple[torch.Tensor, torch.Tensor]:
    """(5, 22) joint membership and (5, L) link membership of the five fingers; (F, J) and (F, L) of a hand from its
    MJCF's F fingers (``DescribedHand.finger_joints``, ``finger_links``)."""
    if is_described(hand):
        joints = torch.zeros(len(hand.finger_joints), len(hand.joint_names), dtype=torch.bool)
        links = torch.zeros(len(hand.finger_links), len(hand.link_names), dtype=torch.bool)
        for f, (finger_joints, finger_links) in enumerate(zip(hand.finger_joints, hand.finger_links)):
            joints[f, list(finger_joints)] = True
            links[f, list(finger_links)] = True
        return joints.to(hand.device), links.to(hand.device)
    joints = torch.tensor([[name.split(":")[1].lower().startswith(f) for name in JOINT_NAMES] for f in FINGERS])
    links = torch.tensor([[name.split(":")[1].startswith(f) for name in hand.link_names] for f in FINGERS])
    return joints.to(hand.device), links.to(hand.device)


def object_signed_distance(bank: SdfBank, points_m: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
    """(B, P) signed distance (m, positive inside) of points (B, P, 3) to the bank's one object at per-grasp scales.

    Uses d_s(x) = s * d_1(x / s) and samples every point as one batch row, so the grid is
    gathered from once instead of copied per grasp (``SdfBank`` indexes a volume per row).
    """
    local = points_m / scale[:, None, None]
    distance, _ = bank.signed_distance(local.reshape(1, -1, 3), torch.zeros(1, dtype=torch.long, device=local.device), torch.ones(1, dtype=local.dtype, device=local.device))
    return distance.reshape(points_m.shape[:2]) * scale[:, None]


@dataclass
class SqueezePlan:
    """Squeeze targets of a batch of grasps and the link depths they were derived from."""

    targets: torch.Tensor  # (B, 22) joint targets, clamped to the joint limits ((B, J) for a hand from its MJCF)
    link_depth_m: torch.Tensor  # (B, L) deepest surface point of each link inside the object (positive inside; -inf: no points)

    @property
    def hand_in_object_m(self) -> torch.Tensor:
        """(B,) deepest hand surface point inside the object (the hand-points direction of initial penetration)."""
        return self.link_depth_m.amax(dim=1)


def _flexion_mask(hand: ShadowHand) -> torch.Tensor:
    """(22,) 1 for the flexion joints J2, J1, J0 of the four fingers, else 0. A hand from its MJCF: (J,) for the joints
    of its fingers that are not opposing (``HandDescription.opposing``), the sign of each joint's larger-magnitude limit
    (the way it flexes) for a joint with an asymmetric range, 0 for the others (side-to-side joints)."""
    if is_described(hand):
        limits = hand.joint_limits.double()
        flex = torch.where(limits[:, 1].abs() > limits[:, 0].abs(), 1.0, -1.0)
        flex = torch.where((limits[:, 1].abs() - limits[:, 0].abs()).abs() < 1e-9, 0.0, flex)
        opposing = {hand.link_index[leaf] for leaf in hand.description.opposing}
        fingers = [joints for joints, links in zip(hand.finger_joints, hand.finger_links) if not opposing & set(links)]
        mask = torch.zeros(len(hand.joint_names), dtype=torch.float64)
        for joints in fingers:
            mask[list(joints)] = flex[list(joints)]
        return mask.to(device=hand.device, dtype=torch.float32)
    names = [name.split(":")[-1] for name in JOINT_NAMES]
    flexion = [name[:2] in ("FF", "MF", "RF", "LF") and name[-2:] in ("J2", "J1", "J0") for name in names]
    return torch.as_tensor(flexion, dtype=torch.float32, device=hand.device)


def squeeze_targets(hand: ShadowHand, bank: SdfBank, hand_pose: torch.Tensor, scale: torch.Tensor, config: LiftConfig) -> SqueezePlan:
    """Joint targets a little past the grasp pose, pushing touching links into the object.

    ``bank`` holds the grasps' one object. A link touches if its deepest surface point is
    within ``squeeze_contact_distance_m`` of the object. Per finger with a touching link,
    the joints move along the gradient of the summed depth of its touching links, scaled
    so the largest change is ``squeeze_rad``; fingers that touch nothing keep their pose.
    """
    finger_joints, finger_links = _finger_masks(hand)
    joints = hand_pose[:, JOINT_COLUMNS].detach().clone().requires_grad_(True)
    pose = torch.cat([hand_pose[:, :6].detach(), joints], dim=1)
    depth = object_signed_distance(bank, hand.surface_points(hand.forward(pose)), scale)
    link_ids = hand.surface_link.expand_as(depth)
    link_depth = torch.full((depth.shape[0], len(hand.link_names)), -math.inf, dtype=depth.dtype, device=depth.device)
    link_depth = link_depth.scatter_reduce(1, link_ids, depth, reduce="amax", include_self=True)
    touching = link_depth > -config.squeeze_contact_distance_m  # (B, L); links without points stay -inf
    objective = torch.where(touching, link_depth, torch.zeros_like(link_depth)).sum()
    (grad,) = torch.autograd.grad(objective, joints)
    delta = torch.zeros_like(grad)
    for f in range(finger_joints.shape[0]):
        active = (touching & finger_links[f]).any(dim=1)  # (B,)
        g = grad * finger_joints[f]
        largest = g.abs().amax(dim=1, keepdim=True)
        step = torch.where(largest > 0, g / largest.clamp(min=1e-12), torch.zeros_like(g)) * config.squeeze_rad
        delta = delta + step * active[:, None]
    if config.preclose_rad > 0:  # a lenient protocol's extra closure of every finger's flexion joints
        delta = delta + config.preclose_rad * _flexion_mask(hand).to(delta.dtype)
    limits = hand.joint_limits.to(delta.dtype)
    targets = (hand_pose[:, JOINT_COLUMNS].detach() + delta).clamp(limits[:, 0], limits[:, 1])
    return SqueezePlan(targets=targets, link_depth_m=link_depth.detach())
