"""Object surface points grouped into small, compact clusters, for exact culling against hand shapes.

Testing every object point against every hand shape near the object is the bulk of E_pen.
Splitting each object's points by median cuts along the widest axis (a k-d tree) gives
clusters of equal size with a bounding sphere each; a shape far from a cluster's sphere
cannot contain any of its points, so most points are never looked at. Points spread per
area number tens of thousands on a large object, so the clusters are grouped once more:
``LEAVES_PER_PARENT`` consecutive clusters of the tree's depth-first order (neighbours in
space) share a parent sphere that holds theirs, and a cluster is tested only if its
parent's sphere meets the shape's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch


LEAVES_PER_PARENT = 16  # clusters under one parent sphere
PADDING = 1.0e3  # normalized coordinate of padding points and padding clusters' centres: far from any hand


@dataclass
class PointClusters:
    """Per object: cluster centres (n, C, 3), radii (n, C), member point indices (n, C, L), −1 = padding;
    parent centres (n, C / LEAVES_PER_PARENT, 3) and radii, parent j holding clusters j·16 … j·16 + 15."""

    centre: torch.Tensor
    radius: torch.Tensor
    members: torch.Tensor
    parent_centre: torch.Tensor
    parent_radius: torch.Tensor


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


def build_point_clusters(points: torch.Tensor, leaf_size: int = 8, counts=None) -> PointClusters:
    """Clusters of ``points`` (n_objects, P, 3), of which object o's first ``counts[o]`` are real (None: all P).

    Objects with fewer clusters are padded with empty clusters far away (radius 0, no members),
    so every object has the same count C, a multiple of ``LEAVES_PER_PARENT``. Radii are computed
    in float64 and rounded up, so every member lies within its cluster's sphere, and every
    cluster's sphere within its parent's, also in float32.
    """
    objects = points.detach().cpu().double().numpy()
    counts = [objects.shape[1]] * len(objects) if counts is None else [int(c) for c in counts]
    all_leaves = [_median_split(p[:c], leaf_size) for p, c in zip(objects, counts)]
    cluster_count = max(len(leaves) for leaves in all_leaves)
    cluster_count = -(-cluster_count // LEAVES_PER_PARENT) * LEAVES_PER_PARENT
    width = max(max(len(leaf) for leaf in leaves) for leaves in all_leaves)
    centre = np.full((len(objects), cluster_count, 3), PADDING)
    radius = np.zeros((len(objects), cluster_count))
    members = np.full((len(objects), cluster_count, width), -1, dtype=np.int64)
    for o, (object_points, leaves) in enumerate(zip(objects, all_leaves)):
        for c, leaf in enumerate(leaves):
            centre[o, c] = object_points[leaf].mean(axis=0)
            radius[o, c] = np.linalg.norm(object_points[leaf] - centre[o, c], axis=1).max() * (1 + 1e-6) + 1e-7
            members[o, c, : len(leaf)] = leaf
    groups = centre.reshape(len(objects), -1, LEAVES_PER_PARENT, 3)
    group_radius = radius.reshape(len(objects), -1, LEAVES_PER_PARENT)
    parent_centre = groups.mean(axis=2)
    parent_radius = (np.linalg.norm(groups - parent_centre[:, :, None], axis=-1) + group_radius).max(axis=2) * (1 + 1e-6) + 1e-7
    as_tensor = lambda array: torch.as_tensor(array, dtype=points.dtype, device=points.device)  # noqa: E731
    return PointClusters(
        centre=as_tensor(centre),
        radius=as_tensor(radius),
        members=torch.as_tensor(members, device=points.device),
        parent_centre=as_tensor(parent_centre),
        parent_radius=as_tensor(parent_radius),
    )
