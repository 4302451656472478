"""Object surface points grouped into small, compact clusters, for exact culling against hand shapes.

Testing every object point against every hand shape near the object is the bulk of E_pen.
Splitting each object's points by median cuts along the widest axis (a k-d tree) gives
clusters of equal size with a bounding sphere each; a shape far from a cluster's sphere
cannot contain any of its points, so most points are never looked at.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch


@dataclass
class PointClusters:
    """Per object: cluster centres (n, C, 3), radii (n, C), member point indices (n, C, L), −1 = padding."""

    centre: torch.Tensor
    radius: torch.Tensor
    members: torch.Tensor


def _median_split(points: np.ndarray, leaf_size: int) -> list[np.ndarray]:
    """Index sets of at most ``leaf_size`` points, by recursive median cuts along the widest axis."""
    pending, leaves = [np.arange(len(points))], []
    while pending:
        index = pending.pop()
        if len(index) <= leaf_size:
            leaves.append(index)
            continue
        extent = points[index].max(axis=0) - points[index].min(axis=0)
        order = index[np.argsort(points[index, int(np.argmax(extent))], kind="stable")]
        half = len(order) // 2
        pending += [order[half:], order[:half]]
    return leaves


def build_point_clusters(points: torch.Tensor, leaf_size: int = 8) -> PointClusters:
    """Clusters of ``points`` (n_objects, P, 3); every object gets the same cluster count (P is shared).

    Radii are computed in float64 and rounded up, so every member lies within its
    cluster's sphere also in float32.
    """
    objects = points.detach().cpu().double().numpy()
    all_leaves = [_median_split(p, leaf_size) for p in objects]  # the same sizes for every object
    cluster_count = len(all_leaves[0])
    width = max(len(leaf) for leaf in all_leaves[0])
    centre = np.zeros((len(objects), cluster_count, 3))
    radius = np.zeros((len(objects), cluster_count))
    members = np.full((len(objects), cluster_count, width), -1, dtype=np.int64)
    for o, (object_points, leaves) in enumerate(zip(objects, all_leaves)):
        for c, leaf in enumerate(leaves):
            centre[o, c] = object_points[leaf].mean(axis=0)
            radius[o, c] = np.linalg.norm(object_points[leaf] - centre[o, c], axis=1).max() * (1 + 1e-6) + 1e-7
            members[o, c, : len(leaf)] = leaf
    return PointClusters(
        centre=torch.as_tensor(centre, dtype=points.dtype, device=points.device),
        radius=torch.as_tensor(radius, dtype=points.dtype, device=points.device),
        members=torch.as_tensor(members, device=points.device),
    )
