"""The refiner: a second look at the surface where a decoded hand lands, and a correction of that pose.

The decoder (or the flow) places the hand from the cloud's PointNet features alone. On an object it has not seen,
its hands start a median of 7-8 mm inside the surface, and most fail the lift test's 2 mm start cap before any push:
the global and per-point features say where the surface is only roughly. The refiner (``model.refiner_hidden``, an
MLP after the decoder) is given what the decoded hand touches: for each of the hand's pad points
(``contact_candidates``) and collision keypoints (``penetration_keypoints``), its height over the tangent plane at
the nearest cloud point (along that point's outward normal: negative inside) and its distance to that point, both
clipped to ``READING_CLIP_M`` and in ``READING_UNIT_M``. It reads them with the decoded pose (in the pose frame) and
the decoder's own inputs, and adds a correction to the pose: one forward pass, no optimization and no mesh, so the
model's output (its raw sample) is the refined pose.

Trained beside the decoder: the decoded pose of each training grasp (from its posterior latent, whose errors on the
training grasps are of the size the sampled poses show on new objects) is refined and compared to the grasp, and the
loss's energies read the refined pose. The reading is a sensor, taken without gradient; the correction's last layer
starts at zero, so an untrained refiner returns the decoded pose.
"""

from __future__ import annotations

import torch

from dexlite_pipeline.model.pose import features_to_parts

READING_CLIP_M = 0.02  # heights and distances beyond 2 cm read as 2 cm: only the surface near the hand matters
READING_UNIT_M = 0.01  # readings in cm, numbers of order 1 for the network
NEAREST_CHUNK_ELEMENTS = 8_000_000  # point-to-cloud distances computed at once (32 MB of float32)


def reading_points(hand) -> int:
    """How many hand points the refiner reads: pad points plus collision keypoints."""
    return len(hand.contact_points_local) + len(hand.keypoints_local)


def reading_width(hand) -> int:
    """The refiner's reading of the surface: a height and a distance per point."""
    return 2 * reading_points(hand)


def hand_points(hand, pose_features: torch.Tensor) -> torch.Tensor:
    """(B, P, 3) the pad points and collision keypoints of hands at ``pose_features`` (B, 9 + J)."""
    frames = hand.forward_parts(*features_to_parts(pose_features))
    return torch.cat([hand.contact_candidates(frames), hand.penetration_keypoints(frames)], dim=1)


@torch.no_grad()
def surface_reading(hand, pose_features: torch.Tensor, clouds: torch.Tensor, cloud_index: torch.Tensor) -> torch.Tensor:
    """(B, 2P) the refiner's reading of hands at ``pose_features`` (B, 9 + J) on ``clouds`` (C, N, 6: points in metres,
    outward normals, in the poses' frame), grasp b on cloud ``cloud_index[b]``: per hand point its height over the
    nearest cloud point's tangent plane, then its distance to that point, clipped and in ``READING_UNIT_M``."""
    if clouds.shape[-1] < 6:
        raise ValueError(f"the refiner reads clouds with normals, (C, N, 6), got {tuple(clouds.shape)}")
    points = hand_points(hand, pose_features)
    heights, distances = [], []
    per_chunk = max(1, NEAREST_CHUNK_ELEMENTS // max(1, points.shape[1] * clouds.shape[1]))
    for start in range(0, len(points), per_chunk):
        chunk = points[start:start + per_chunk]
        cloud = clouds[cloud_index[start:start + per_chunk]]  # (b, N, 6)
        nearest = torch.cdist(chunk, cloud[..., :3]).argmin(dim=2)  # (b, P)
        picked = torch.gather(cloud, 1, nearest[..., None].expand(-1, -1, cloud.shape[-1]))  # (b, P, 6)
        offset = chunk - picked[..., :3]
        heights.append((offset * picked[..., 3:6]).sum(dim=2))
        distances.append(offset.norm(dim=2))
    height = torch.cat(heights).clamp(-READING_CLIP_M, READING_CLIP_M)
    distance = torch.cat(distances).clamp(max=READING_CLIP_M)
    return torch.cat([height, distance], dim=1) / READING_UNIT_M
