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

import numba
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


@numba.njit(cache=True)
def _median_split(points: np.ndarray, leaf_size: int) -> tuple[np.ndarray, np.ndarray]:
    """Index sets of at most ``leaf_size`` points, by recursive median cuts along the widest axis (first of equal
    extents), the lower half first: a permutation of the points and each leaf's (start, stop) in it, depth-first."""
    order = np.arange(points.shape[0])
    bounds = np.empty((max(1, 2 * points.shape[0] // max(leaf_size // 2, 1) + 2), 2), np.int64)
    leaves = 0
    pending = [(0, points.shape[0])]
    while pending:
        lo, hi = pending.pop()
        if hi - lo <= leaf_size:
            bounds[leaves, 0], bounds[leaves, 1] = lo, hi
            leaves += 1
            continue
        index = order[lo:hi]
        axis, widest = 0, -1.0
        for a in range(3):
            extent = points[index, a].max() - points[index, a].min()
            if extent > widest:
                axis, widest = a, extent
        order[lo:hi] = index[np.argsort(points[index, axis], kind="mergesort")]
        half = (hi - lo) // 2
        pending.append((lo + half, hi))
        pending.append((lo, lo + half))
    return order, bounds[:leaves]


@numba.njit(cache=True)
def _leaf_spheres(points, order, bounds, centre, radius, members) -> None:
    """Each leaf's mean point, the distance to its farthest member (rounded up, so float32 keeps it a bound) and
    its members, written into ``centre`` (C, 3), ``radius`` (C,), ``members`` (C, L)."""
    for c in range(bounds.shape[0]):
        start, stop = bounds[c, 0], bounds[c, 1]
        for a in range(3):
            total = 0.0
            for i in range(start, stop):
                total += points[order[i], a]
            centre[c, a] = total / (stop - start)
        farthest = 0.0
        for i in range(start, stop):
            p = order[i]
            farthest = max(farthest, np.sqrt((points[p, 0] - centre[c, 0]) ** 2 + (points[p, 1] - centre[c, 1]) ** 2 + (points[p, 2] - centre[c, 2]) ** 2))
            members[c, i - start] = p
        radius[c] = farthest * (1 + 1e-6) + 1e-7


def build_point_clusters(points: torch.Tensor, leaf_size: int = 8, counts=None) -> PointClusters:
    """Clusters of ``points`` (n_objects, P, 3), of which object o's first ``counts[o]`` are real (None: all P).

    Objects with fewer clusters are padded with empty clusters far away (radius 0, no members),
    so every object has the same count C, a multiple of ``LEAVES_PER_PARENT``. Radii are computed
    in float64 and rounded up, so every member lies within its cluster's sphere, and every
    cluster's sphere within its parent's, also in float32.
    """
    objects = points.detach().cpu().double().numpy()
    counts = [objects.shape[1]] * len(objects) if counts is None else [int(c) for c in counts]
    splits = [_median_split(np.ascontiguousarray(p[:c]), leaf_size) for p, c in zip(objects, counts)]
    cluster_count = max(len(bounds) for _, bounds in splits)
    cluster_count = -(-cluster_count // LEAVES_PER_PARENT) * LEAVES_PER_PARENT
    width = max(int((bounds[:, 1] - bounds[:, 0]).max()) if len(bounds) else 0 for _, bounds in splits)
    centre = np.full((len(objects), cluster_count, 3), PADDING)
    radius = np.zeros((len(objects), cluster_count))
    members = np.full((len(objects), cluster_count, width), -1, dtype=np.int64)
    for o, (order, bounds) in enumerate(splits):
        _leaf_spheres(objects[o], order, bounds, centre[o], radius[o], members[o])
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
