"""How deep a hand reaches below a table: the exact lowest point of its collision shapes along the table's normal.

The energy's E_table term, the lift test's start check, curation's ``below_table`` filter and the
evaluation's reachability column all measure it here; the planes come from ``tabletop``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dexlite_pipeline.objects.rest_pose import SupportPlane

if TYPE_CHECKING:
    from dexlite_pipeline.tabletop import SupportPlanes


class HandTableClearance:
    """Exact lowest point of each of the hand's collision shapes along a table normal (torch, differentiable).

    A capsule along its local z (radius r, half length L) reaches n·c − L·|n·z_s| − r, a box of
    half extents e reaches n·c − Σ e_i·|n·axis_i|: the support function of the shape, so no
    sampled point can miss a corner. These are the shapes MuJoCo simulates.
    """

    def __init__(self, hand) -> None:
        import torch

        from dexlite_pipeline.energy.link_map import LinkFrameMap
        from dexlite_pipeline.hand.model import CAPSULE

        self.shape_map = LinkFrameMap.for_frames(hand.shape_rot, hand.shape_pos, hand.shape_link, len(hand.link_names))
        capsule = hand.shape_kind == CAPSULE
        size = hand.shape_size
        zeros = torch.zeros_like(size[:, 0])
        self.half_extent = torch.where(capsule[:, None], torch.stack([zeros, zeros, size[:, 1]], dim=1), size)  # (S, 3)
        self.radius = torch.where(capsule, size[:, 0], zeros)  # (S,)

    def lowest_heights(self, frames, normal, offset_m):
        """(B, S) height (m) of each shape's lowest point above the table (negative: below), normal (B, 3), offset (B,)."""
        frame = self.shape_map(frames)  # (B, S, 3, 4): [R | c]
        along = (frame[..., :3] * normal[:, None, :, None]).sum(2)  # (B, S, 3): n·axis_i
        centre = (frame[..., 3] * normal[:, None, :]).sum(-1) + offset_m[:, None]
        return centre - (along.abs() * self.half_extent).sum(-1) - self.radius

    def depth_below(self, frames, normal, offset_m):
        """(B,) deepest hand point below the table (m; 0 when the hand is wholly above it)."""
        return (-self.lowest_heights(frames, normal, offset_m)).clamp(min=0).amax(dim=1)


def hand_table_depth(hand, hand_pose: np.ndarray, plane: SupportPlane, scale: np.ndarray) -> np.ndarray:
    """(B,) deepest point of the hand's collision shapes below ``plane`` (m, 0 if wholly above) for stored poses (B, 28) at ``scale`` (B,)."""
    import torch

    pose = torch.as_tensor(np.asarray(hand_pose), dtype=hand.dtype, device=hand.device)
    scale = np.asarray(scale, dtype=np.float64)
    with torch.no_grad():
        frames = hand.forward(pose)
        normal = torch.as_tensor(np.tile(plane.normal, (len(scale), 1)), dtype=hand.dtype, device=hand.device)
        offset = torch.as_tensor(plane.offset * scale, dtype=hand.dtype, device=hand.device)
        return HandTableClearance(hand).depth_below(frames, normal, offset).cpu().numpy().astype(np.float64)


def grasp_table_depths(grasps, planes: SupportPlanes, hand=None, batch: int = 1024) -> np.ndarray:
    """(N,) deepest hand point below each grasp's table (m; 0: wholly above; NaN: no plane for its object or a non-finite pose)."""
    from dexlite_pipeline.hand.model import ShadowHand

    hand = hand or ShadowHand()
    depth = np.full(len(grasps), np.nan)
    ids = np.asarray([str(o) for o in grasps.object_id])
    finite = np.isfinite(grasps.hand_pose).all(axis=1) & np.isfinite(grasps.scale)
    for object_id in sorted(set(ids[finite].tolist())):
        if object_id not in planes:
            continue
        rows = np.flatnonzero((ids == object_id) & finite)
        for start in range(0, len(rows), batch):
            part = rows[start : start + batch]
            depth[part] = hand_table_depth(hand, grasps.hand_pose[part], planes.get(object_id), grasps.scale[part])
    return depth




def raise_above_table(grasps, planes: SupportPlanes, hand=None):
    """The grasps with each hand below its table moved up along the table's normal until it touches
    it from above (a start the optimizer can repair from), and the shift of each (m, 0: unmoved).
    ``hand``: the hand model of the poses (None: the Shadow Hand)."""
    from dexlite_pipeline.io.grasp_store import GraspSet

    shift = np.nan_to_num(grasp_table_depths(grasps, planes, hand), nan=0.0)
    moved = GraspSet(dict(grasps.arrays), dict(grasps.attrs))
    pose = grasps.hand_pose.copy()
    for i in np.flatnonzero(shift > 0):
        pose[i, :3] += np.asarray(planes.get(str(grasps.object_id[i])).normal, dtype=np.float32) * np.float32(shift[i])
    moved.arrays["hand_pose"] = pose
    return moved, shift
