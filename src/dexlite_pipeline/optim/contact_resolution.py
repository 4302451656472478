"""Contact resolution: the last phase of an optimization, backing the hand out of the object.

The annealed optimizer trades E_pen against the other terms with fixed weights, so it ends
with some grasps pressed a few millimetres into the object, and the lift test refuses a grasp
that starts deeper than its cap (a hand could not have reached it without passing through the
object). Filtering those afterwards wastes them; instead every optimization ends here: a grasp
whose penetration depth (the measure of ``energy.penetration_term.PenetrationTerm``, against the mesh)
exceeds ``allowed_m`` moves, a small step at a time (longer while it is far from done, below),
until it is within ``allowed_m`` or the steps run out: its joint angles down the gradient of its
squared excess depth (``PenetrationTerm.excess``), so a finger inside the object opens along its
closing direction reversed, and its palm position, orientation kept, for the first
``FINGERS_FIRST_STEPS`` steps down the gradient of the palm's own excess only, so the palm backs off
where the palm is inside and stays put where a finger can get out alone (moving it pulls every other
contact off the surface), then down the whole hand's, for a finger that its joints cannot take out
(one pressed in along its length). A finger that only touches is not moved. Grasps already within
``allowed_m`` are returned unchanged.

A grasp far from done takes longer steps: each step is the base step (``JOINT_STEP_RAD``,
``TRANSLATION_STEP_M``) times its excess depth (in the object beyond ``allowed_m``, or below the
table) over ``STEP_GROWTH_DEPTH_M``, at least 1 and at most ``MAX_STEP_GROWTH``. Grasps that start
a centimetre or more inside the object then back out within the steps instead of running out of
them, in fewer steps, and every grasp ends its resolution with base steps (within a millimetre of done).

On a table (tabletop mode: the energy has support planes) the hand must also end wholly above
it: the lift test refuses a grasp with any hand shape below the table, and the optimizer's E_table
(linear in depth, like E_pen) leaves some grasps a few millimetres in it. Each shape's lowest point
below ``TABLE_CLEARANCE_M`` above the table adds its squared shortfall to the excess descended, with
the same split between the palm and the fingers, and a grasp is resolved only when no shape
reaches below the table.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from dexlite_pipeline.energy.grasp_energy import GraspEnergy
from dexlite_pipeline.hand.model import JOINTS, HandFrames

JOINT_STEP_RAD = 0.005  # largest joint change per step (a fingertip ~10 cm from its joint moves ≤ 0.5 mm)
TRANSLATION_STEP_M = 0.0002  # palm movement per step where the palm's gradient points out
RESOLUTION_STEPS = 60  # at most this many steps (at base length ≤ 0.3 rad and 12 mm in all)
STEP_GROWTH_DEPTH_M = 0.001  # a step is the base step times the grasp's excess depth over this (m) ...
MAX_STEP_GROWTH = 4.0  # ... at most this many times (0.02 rad, 0.8 mm)
FINGERS_FIRST_STEPS = 20  # steps in which the palm backs off only where the palm itself is inside
PALM_LINK = "robot0:palm"  # the Shadow Hand's root link: its shapes move only with the palm (no joint between them)
ROOT_LINK = 0  # the root link's index, any hand's (``robot0:palm`` on the Shadow Hand, a description's ``links[0]``)
JOINT_COLUMNS = slice(JOINTS.start, None)  # a stored pose's joints: 22 on the Shadow Hand, J on a hand from its MJCF
TABLE_CLEARANCE_M = 1e-4  # the excess pushes each shape's lowest point this far above the table (m), so a grasp ends clear of it


@dataclass
class ResolvedContacts:
    """Poses after resolution (B, 28), their depth in the object before and after (m), how far below the table the
    hand reaches after (m, 0 when clear or floating), and how many steps each took."""

    hand_pose: torch.Tensor
    depth_before_m: torch.Tensor
    depth_m: torch.Tensor
    table_depth_m: torch.Tensor
    steps: torch.Tensor


class TableShortfall:
    """How far each hand shape's lowest point lies under ``TABLE_CLEARANCE_M`` above its grasp's table (tabletop mode)."""

    def __init__(self, energy: GraspEnergy) -> None:
        from dexlite_pipeline.energy.table_clearance import HandTableClearance

        self.energy = energy
        self.clearance = HandTableClearance(energy.hand)

    def heights(self, frames: HandFrames, object_index: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
        """(B, S) height of each shape's lowest point above the table, m (negative: below)."""
        normal, offset = self.energy.support(object_index, scale)
        return self.clearance.lowest_heights(frames, normal, offset)

    def excess_and_depth(
        self, frames: HandFrames, object_index: torch.Tensor, scale: torch.Tensor, shapes: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor | None, torch.Tensor]:
        """From one pass: (B,) Σ max(0, clearance − height)² over the hand's shapes, the same over ``shapes`` (S,) bool
        alone (None without ``shapes``), both differentiable, and (B,) ``depth_m`` (detached)."""
        heights = self.heights(frames, object_index, scale)
        shortfall = torch.relu(TABLE_CLEARANCE_M - heights).square()
        only = (shortfall * shapes.to(shortfall.dtype)).sum(dim=1) if shapes is not None else None
        return shortfall.sum(dim=1), only, self._below(heights.detach())

    def depth_m(self, frames: HandFrames, object_index: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
        """(B,) the deepest hand point below the table, m (0 when the hand is wholly above it)."""
        return self._below(self.heights(frames, object_index, scale))

    @staticmethod
    def _below(heights: torch.Tensor) -> torch.Tensor:
        return (-heights).clamp(min=0).amax(dim=1)


def penetration_depth_m(energy: GraspEnergy, hand_pose: torch.Tensor, object_index: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
    """(B,) the judged penetration depth (m): the measure against the mesh near the surface."""
    return energy.judged_depth_m(energy.hand.forward(hand_pose.detach()), object_index, scale)


def resolve_contacts(
    energy: GraspEnergy, hand_pose: torch.Tensor, object_index: torch.Tensor, scale: torch.Tensor, allowed_m: float, steps: int = RESOLUTION_STEPS
) -> ResolvedContacts:
    """Back each grasp deeper than ``allowed_m`` out of its object, and out of its table (module docstring)."""
    pose = hand_pose.detach().clone()
    scale = scale.to(pose.dtype)
    table = TableShortfall(energy) if energy.support_planes is not None else None

    def depths(poses: torch.Tensor, rows: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(depth in the object, depth below the table) of ``poses``, grasps ``rows``, from one kinematics pass."""
        with torch.no_grad():
            frames = energy.hand.forward(poses)
            in_object = energy.judged_depth_m(frames, object_index[rows], scale[rows])
            below = table.depth_m(frames, object_index[rows], scale[rows]) if table is not None else torch.zeros_like(in_object)
        return in_object, below

    every = torch.arange(len(pose), device=pose.device)
    depth_before, table_depth = depths(pose, every)
    depth = depth_before.clone()
    taken = torch.zeros(len(pose), dtype=torch.long, device=pose.device)
    limits = energy.hand.joint_limits.to(pose.dtype)
    palm = energy.hand.shape_link == ROOT_LINK  # (S,) the palm's own shapes
    rows = ((depth > allowed_m) | (table_depth > 0)).nonzero().squeeze(1)
    for step in range(steps):
        if len(rows) == 0:
            break
        # One pass at the rows' current poses gives their depths (which grasps are done) and the excesses to descend.
        moving = pose[rows].clone().requires_grad_(True)
        frames = energy.hand.forward(moving)
        obj, sc = object_index[rows], scale[rows]
        fingers_first = step < FINGERS_FIRST_STEPS
        whole, palm_only, in_object = energy.judge.excess_and_depth(frames, obj, sc, allowed_m, palm if fingers_first else None)
        if step > 0:
            depth[rows] = in_object
        below = torch.zeros_like(in_object)
        if table is not None:
            table_whole, table_palm, below = table.excess_and_depth(frames, obj, sc, palm if fingers_first else None)
            whole = whole + table_whole
            palm_only = palm_only + table_palm if palm_only is not None else None
            if step > 0:
                table_depth[rows] = below
        unresolved = (in_object > allowed_m) | (below > 0)
        if not bool(unresolved.any()):
            rows = rows[:0]
            break
        (gradient,) = torch.autograd.grad(whole.sum(), moving, retain_graph=palm_only is not None)
        joint_gradient, palm_gradient = gradient[:, JOINT_COLUMNS], gradient[:, :3]
        if palm_only is not None:  # the palm moves for its own shapes only, while the fingers may still get out alone
            palm_gradient = torch.autograd.grad(palm_only.sum(), moving)[0][:, :3] if bool(palm_only.gt(0).any()) else torch.zeros_like(palm_gradient)
        largest = joint_gradient.abs().amax(dim=1, keepdim=True)
        joint_step = torch.where(largest > 0, joint_gradient / largest.clamp(min=1e-30), torch.zeros_like(joint_gradient)) * JOINT_STEP_RAD
        palm_norm = palm_gradient.norm(dim=1, keepdim=True)
        palm_step = torch.where(palm_norm > 0, palm_gradient / palm_norm.clamp(min=1e-30), torch.zeros_like(palm_gradient)) * TRANSLATION_STEP_M
        growth = (torch.maximum(in_object - allowed_m, below) / STEP_GROWTH_DEPTH_M).clamp(1.0, MAX_STEP_GROWTH)[:, None]
        joint_step, palm_step = joint_step * growth, palm_step * growth
        keep = unresolved.nonzero().squeeze(1)  # resolved rows stay where they are
        updated = pose[rows].clone()
        updated[:, JOINT_COLUMNS] = (updated[:, JOINT_COLUMNS] - joint_step).clamp(limits[:, 0], limits[:, 1])
        updated[:, :3] = updated[:, :3] - palm_step
        rows = rows[keep]
        pose[rows] = updated[keep]
        taken[rows] += 1
    if len(rows):  # the last step's poses: their depths after it
        depth[rows], table_depth[rows] = depths(pose[rows], rows)
    return ResolvedContacts(hand_pose=pose, depth_before_m=depth_before, depth_m=depth, table_depth_m=table_depth, steps=taken)
