"""E_pen of a batch in one compiled CPU pass (numba), with its gradient in the link frames.

``PenetrationTerm`` written as a few thousand small torch operations spends most of an
energy step on per-operation overhead and on gathering candidate rows (measured: 65-95%
of a step). This module computes the same quantities grasp by grasp in one loop:

- hand in object: every sphere's centre from its link frame, its trilinear SDF value and
  gradient (the grid's, ``grid_kernel``), the deepest sphere per shape
  (which shapes are active), and Σ d(c) over the centres inside the object;
- object in hand: for each active shape, the object's clusters (``point_clusters``) whose
  parent's and own bounding sphere the shape may reach (the shape's depth, 1-Lipschitz, at
  the sphere's centre above −radius), their member points among the grasp's own prefix,
  each point's analytic depth in the capsule or box; a point inside several shapes counts
  once, at its deepest (exact ties share it, as ``torch.amax``'s gradient does);
- the gradient of E_pen with respect to each link's rotation (3, 3) and translation (3),
  accumulated in the same pass, so backward is one multiplication.

The culling may admit more clusters than the torch path (it is only a bound); which points
count is decided by the exact depth test, so both paths count the same points. Arithmetic is
float64 inside; the grids and points are read as stored (float32). Each grasp is computed on
its own, so its result never depends on the rest of its batch. The culling loops read the
clusters as one array per coordinate and are written without calls or allocations, so they
compile to vector code; hot loops never reassign an array (numba would then count references
at every iteration, which measured 2x slower).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
import torch

from dexlite_pipeline.energy.frame_gradient import attach, frame_arrays, wants_gradient
from dexlite_pipeline.energy.grid_kernel import grid_distance
from dexlite_pipeline.energy.point_clusters import LEAVES_PER_PARENT, PADDING
from dexlite_pipeline.hand.model import CAPSULE

# Slack of the cluster-centre depth test, metres (rounding never drops a cluster).
_DEPTH_SLACK_M = 1e-6
# sqrt(1e-18): the torch path's guard inside square roots, kept so depths match it exactly.
_SQRT_EPS = 1e-18


@numba.njit(cache=True, nogil=True, inline="always")
def _shape_depth(kind, size0, size1, size2, lx, ly, lz):
    """Depth (positive inside, metres) of a point in its shape's frame: a capsule along z (radius ``size0``,
    half length ``size1``) or a box (half extents ``size0..2``); the torch path's formulas."""
    if kind == CAPSULE:
        az = lz - min(max(lz, -size1), size1)
        return size0 - math.sqrt(lx * lx + ly * ly + az * az + _SQRT_EPS)
    qx, qy, qz = abs(lx) - size0, abs(ly) - size1, abs(lz) - size2
    outside = math.sqrt(max(qx, 0.0) ** 2 + max(qy, 0.0) ** 2 + max(qz, 0.0) ** 2 + _SQRT_EPS)
    return -(outside + min(max(qx, qy, qz), 0.0))


@numba.njit(cache=True, nogil=True, inline="always")
def _depth_at(kind, size0, size1, size2, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, s, x, y, z):
    """``_shape_depth`` of the normalized point (x, y, z) at scale ``s``, for a shape at [R | p] (metres)."""
    vx, vy, vz = s * x - px, s * y - py, s * z - pz
    return _shape_depth(kind, size0, size1, size2, r00 * vx + r10 * vy + r20 * vz, r01 * vx + r11 * vy + r21 * vz, r02 * vx + r12 * vy + r22 * vz)


@numba.njit(cache=True, nogil=True, inline="always")
def _shape_depth_gradient(kind, size0, size1, size2, lx, ly, lz, gradient):
    """The gradient (3,) of ``_shape_depth`` at a point inside the shape, written into ``gradient``."""
    if kind == CAPSULE:
        az = lz - min(max(lz, -size1), size1)
        norm = math.sqrt(lx * lx + ly * ly + az * az + _SQRT_EPS)
        gradient[0], gradient[1], gradient[2] = -lx / norm, -ly / norm, -az / norm
        return
    qx, qy, qz = abs(lx) - size0, abs(ly) - size1, abs(lz) - size2
    gradient[0] = gradient[1] = gradient[2] = 0.0
    # Inside a box the depth is the nearest face's distance: its axis (the first of equals, as torch's max).
    if qx >= qy and qx >= qz:
        gradient[0] = -1.0 if lx > 0 else (1.0 if lx < 0 else 0.0)
    elif qy >= qz:
        gradient[1] = -1.0 if ly > 0 else (1.0 if ly < 0 else 0.0)
    else:
        gradient[2] = -1.0 if lz > 0 else (1.0 if lz < 0 else 0.0)


@numba.njit(cache=True, nogil=True)
def _one_grasp(
    b, rotation, translation, o, s, count, weight, want_gradient, arrays,
    energy, object_max, hand_max, grad_rotation, grad_translation, hit_point, hit_shape, hit_depth,
):
    """E_pen of grasp ``b`` into ``energy[b]`` etc.; returns the number of hits, which must not exceed the buffers'
    length (else nothing is final: the caller calls again with longer buffers)."""
    (volumes, grid_min, voxel_size, interpolation_error, sphere_centre, sphere_radius, sphere_link, sphere_shape, shape_link,
     shape_rot, shape_pos, shape_kind, shape_size, shape_gap, points, parent_x, parent_y, parent_z, parent_r, cluster_x,
     cluster_y, cluster_z, cluster_r, member_x, member_y, member_z, member_index, leaves_per_parent) = arrays
    g = volumes.shape[1]
    if want_gradient:
        grad_rotation[b] = 0.0
        grad_translation[b] = 0.0
    h = voxel_size[o]
    shape_count = shape_link.shape[0]
    reach = np.full(shape_count, -np.inf)
    gradient = np.empty(3)
    hand_energy = 0.0
    deepest_sphere = 0.0
    # Hand in object: spheres.
    for k in range(sphere_centre.shape[0]):
        link = sphere_link[k]
        x, y, z = sphere_centre[k, 0], sphere_centre[k, 1], sphere_centre[k, 2]
        cx = rotation[b, link, 0, 0] * x + rotation[b, link, 0, 1] * y + rotation[b, link, 0, 2] * z + translation[b, link, 0]
        cy = rotation[b, link, 1, 0] * x + rotation[b, link, 1, 1] * y + rotation[b, link, 1, 2] * z + translation[b, link, 1]
        cz = rotation[b, link, 2, 0] * x + rotation[b, link, 2, 1] * y + rotation[b, link, 2, 2] * z + translation[b, link, 2]
        distance = grid_distance(volumes, o, g, grid_min, h, cx / s, cy / s, cz / s, gradient) * s
        depth = distance + sphere_radius[k]
        shape = sphere_shape[k]
        if depth > reach[shape]:
            reach[shape] = depth
        if depth > deepest_sphere:
            deepest_sphere = depth
        if distance > 0.0:  # the centre is inside the object
            hand_energy += distance
            if want_gradient:
                for a in range(3):
                    grad_translation[b, link, a] += gradient[a]
                    for j in range(3):
                        grad_rotation[b, link, a, j] += gradient[a] * sphere_centre[k, j]
    hand_max[b] = deepest_sphere
    # Object in hand: points of the grasp's prefix inside the active shapes.
    margin = interpolation_error[o] * s
    frame = np.zeros((shape_count, 12))  # per shape [R row-major | c], metres
    capacity = hit_point.shape[0]
    hits = 0
    width = member_index.shape[1] // cluster_x.shape[1]  # points per cluster slot
    parent_open = np.empty(parent_x.shape[1], np.bool_)
    leaf_open = np.empty(leaves_per_parent, np.bool_)
    for shape in range(shape_count):
        if not reach[shape] > -(margin + shape_gap[shape]):
            continue
        link = shape_link[shape]
        for a in range(3):
            for j in range(3):
                frame[shape, 3 * a + j] = (rotation[b, link, a, 0] * shape_rot[shape, 0, j] + rotation[b, link, a, 1] * shape_rot[shape, 1, j]
                                           + rotation[b, link, a, 2] * shape_rot[shape, 2, j])
            frame[shape, 9 + a] = (rotation[b, link, a, 0] * shape_pos[shape, 0] + rotation[b, link, a, 1] * shape_pos[shape, 1]
                                   + rotation[b, link, a, 2] * shape_pos[shape, 2] + translation[b, link, a])
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = (frame[shape, 0], frame[shape, 1], frame[shape, 2], frame[shape, 3], frame[shape, 4],
                                                       frame[shape, 5], frame[shape, 6], frame[shape, 7], frame[shape, 8])
        px, py, pz = frame[shape, 9], frame[shape, 10], frame[shape, 11]
        kind = shape_kind[shape]
        size0, size1, size2 = shape_size[shape, 0], shape_size[shape, 1], shape_size[shape, 2]
        # Two levels of culling, each one vectorizable loop: the shape's depth (1-Lipschitz) at each parent sphere's
        # centre must come within its radius, then at each of its clusters'; then the clusters' points themselves.
        parents = parent_x.shape[1]
        for j in range(parents):
            parent_open[j] = _depth_at(kind, size0, size1, size2, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, s,
                                       parent_x[o, j], parent_y[o, j], parent_z[o, j]) + parent_r[o, j] * s > -_DEPTH_SLACK_M
        for j in range(parents):
            if not parent_open[j]:
                continue
            first = j * leaves_per_parent
            for c in range(leaves_per_parent):
                cluster = first + c
                leaf_open[c] = _depth_at(kind, size0, size1, size2, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, s,
                                         cluster_x[o, cluster], cluster_y[o, cluster], cluster_z[o, cluster]) + cluster_r[o, cluster] * s > -_DEPTH_SLACK_M
            for c in range(leaves_per_parent):
                if not leaf_open[c]:
                    continue
                start = (first + c) * width
                for m in range(start, start + width):
                    depth = _depth_at(kind, size0, size1, size2, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, s,
                                      member_x[o, m], member_y[o, m], member_z[o, m])
                    if depth > 0.0:
                        point = member_index[o, m]
                        if point >= 0 and point < count:
                            if hits < capacity:
                                hit_point[hits] = point
                                hit_shape[hits] = shape
                                hit_depth[hits] = depth
                            hits += 1
    if hits > capacity:
        return hits  # the caller grows the buffers and calls again
    object_energy = 0.0
    deepest_point = 0.0
    if hits > 0:
        order = np.argsort(hit_point[:hits], kind="mergesort")
        grad_frame = np.zeros((shape_count, 12))  # dE/d[R row-major | c] per shape
        start = 0
        while start < hits:
            stop = start
            best = 0.0
            while stop < hits and hit_point[order[stop]] == hit_point[order[start]]:
                best = max(best, hit_depth[order[stop]])
                stop += 1
            ties = 0
            for i in range(start, stop):
                if hit_depth[order[i]] == best:
                    ties += 1
            deepest_point = max(deepest_point, best)
            coefficient = weight / ties
            for i in range(start, stop):
                hit = order[i]
                if hit_depth[hit] != best:
                    continue
                object_energy += coefficient * best
                if not want_gradient:
                    continue
                shape = hit_shape[hit]
                point = hit_point[hit]
                vx = s * points[o, point, 0] - frame[shape, 9]
                vy = s * points[o, point, 1] - frame[shape, 10]
                vz = s * points[o, point, 2] - frame[shape, 11]
                lx = frame[shape, 0] * vx + frame[shape, 3] * vy + frame[shape, 6] * vz
                ly = frame[shape, 1] * vx + frame[shape, 4] * vy + frame[shape, 7] * vz
                lz = frame[shape, 2] * vx + frame[shape, 5] * vy + frame[shape, 8] * vz
                _shape_depth_gradient(shape_kind[shape], shape_size[shape, 0], shape_size[shape, 1], shape_size[shape, 2], lx, ly, lz, gradient)
                # local = Rₛᵀ v with v = s·p − cₛ: ∂local_i/∂Rₛ[j, i] = v_j, ∂local/∂cₛ = −Rₛ.
                for j, v in enumerate((vx, vy, vz)):
                    for i in range(3):
                        grad_frame[shape, 3 * j + i] += coefficient * gradient[i] * v
                    grad_frame[shape, 9 + j] -= coefficient * (frame[shape, 3 * j] * gradient[0] + frame[shape, 3 * j + 1] * gradient[1]
                                                               + frame[shape, 3 * j + 2] * gradient[2])
            start = stop
        if want_gradient:
            # Rₛ = R·Q and cₛ = R·q + t for the shape's fixed offset (Q, q) in its link.
            for shape in range(shape_count):
                link = shape_link[shape]
                for a in range(3):
                    grad_translation[b, link, a] += grad_frame[shape, 9 + a]
                    for j in range(3):
                        grad_rotation[b, link, a, j] += (grad_frame[shape, 3 * a] * shape_rot[shape, j, 0] + grad_frame[shape, 3 * a + 1] * shape_rot[shape, j, 1]
                                                         + grad_frame[shape, 3 * a + 2] * shape_rot[shape, j, 2] + grad_frame[shape, 9 + a] * shape_pos[shape, j])
    object_max[b] = deepest_point
    energy[b] = object_energy + hand_energy
    return hits


@numba.njit(cache=True, nogil=True)
def _penetration_batch(rotation, translation, object_index, scale, count, weight, want_gradient, initial_hits, arrays):
    batch, links = rotation.shape[0], rotation.shape[1]
    energy = np.zeros(batch)
    object_max = np.zeros(batch)
    hand_max = np.zeros(batch)
    grad_rotation = np.zeros((batch, links, 3, 3)) if want_gradient else np.zeros((0, links, 3, 3))
    grad_translation = np.zeros((batch, links, 3)) if want_gradient else np.zeros((0, links, 3))
    hit_point = np.empty(initial_hits, np.int64)
    hit_shape = np.empty(initial_hits, np.int64)
    hit_depth = np.empty(initial_hits)
    for b in range(batch):
        while True:
            hits = _one_grasp(
                b, rotation, translation, object_index[b], scale[b], count[b], weight[b], want_gradient, arrays,
                energy, object_max, hand_max, grad_rotation, grad_translation, hit_point, hit_shape, hit_depth,
            )
            if hits <= hit_point.shape[0]:
                break
            hit_point = np.empty(2 * hits, np.int64)  # rare: a hand deep in a densely sampled object
            hit_shape = np.empty(2 * hits, np.int64)
            hit_depth = np.empty(2 * hits)
    return energy, object_max, hand_max, grad_rotation, grad_translation


def cluster_arrays(clusters, object_points: torch.Tensor) -> tuple[np.ndarray, ...]:
    """``PointClusters`` as flat float64 arrays per object, one per coordinate (so the culling loops vectorize):
    parent centres x, y, z and radii (n, P); cluster centres x, y, z and radii (n, C); the members' points x, y, z
    (n, C·L), L slots per cluster in order, and their indices (n, C·L), −1 for empty slots (placed far away)."""
    def coordinates(tensor):
        values = tensor.detach().cpu().double().numpy()
        return tuple(np.ascontiguousarray(values[..., a]) for a in range(3))

    def radii(tensor):
        return np.ascontiguousarray(tensor.detach().cpu().double().numpy())

    members = clusters.members.detach().cpu().numpy().astype(np.int64)
    objects, count, width = members.shape
    member_index = members.reshape(objects, count * width)
    member_points = np.take_along_axis(object_points.detach().cpu().double().numpy(), np.clip(member_index, 0, None)[..., None], axis=1)
    member_points[member_index < 0] = PADDING
    return (
        *coordinates(clusters.parent_centre), radii(clusters.parent_radius),
        *coordinates(clusters.centre), radii(clusters.radius),
        *coordinates(torch.from_numpy(member_points)), member_index,
    )


class PenetrationArrays(NamedTuple):
    """The static arrays of one ``PenetrationTerm`` the compiled pass reads, in its order (passed as a plain tuple)."""

    volumes: np.ndarray  # (n, g, g, g) SDF grids, normalized units, positive inside
    grid_min: np.ndarray  # (n, 3)
    voxel_size: np.ndarray  # (n,)
    interpolation_error: np.ndarray  # (n,) the grid's error bound, normalized units
    sphere_centre: np.ndarray  # (K, 3) in link frames, m
    sphere_radius: np.ndarray  # (K,)
    sphere_link: np.ndarray  # (K,)
    sphere_shape: np.ndarray  # (K,)
    shape_link: np.ndarray  # (S,)
    shape_rot: np.ndarray  # (S, 3, 3) in link frames
    shape_pos: np.ndarray  # (S, 3)
    shape_kind: np.ndarray  # (S,) CAPSULE or BOX
    shape_size: np.ndarray  # (S, 3)
    shape_gap: np.ndarray  # (S,) covering gap of the shape's spheres, m
    points: np.ndarray  # (n, P, 3) object points, normalized
    parent_x: np.ndarray  # (n, C / 16) and the next three: parent spheres
    parent_y: np.ndarray
    parent_z: np.ndarray
    parent_r: np.ndarray
    cluster_x: np.ndarray  # (n, C) and the next three: cluster spheres
    cluster_y: np.ndarray
    cluster_z: np.ndarray
    cluster_r: np.ndarray
    member_x: np.ndarray  # (n, C·L) and the next two: member points; member_index: their indices, −1 empty
    member_y: np.ndarray
    member_z: np.ndarray
    member_index: np.ndarray
    leaves_per_parent: int


class PenetrationKernel:
    """The static arrays of one ``PenetrationTerm`` as NumPy views, and its compiled evaluation."""

    initial_hits = 1024  # hits (object points inside a shape) one grasp may have before the buffers grow

    def __init__(self, term) -> None:
        def array(tensor, dtype):
            return np.ascontiguousarray(tensor.detach().cpu().numpy().astype(dtype, copy=False))

        bank, hand, spheres, clusters = term.bank, term.hand, term.spheres, term.clusters
        g = bank.resolution
        self.static = PenetrationArrays(
            array(bank.volumes, np.float32).reshape(-1, g, g, g),
            array(bank.grid_min, np.float64),
            array(bank.voxel_size, np.float64),
            array(term.interpolation_error, np.float64),
            array(spheres.centre_local, np.float64),
            array(spheres.radius, np.float64),
            array(spheres.link, np.int64),
            array(spheres.shape, np.int64),
            array(hand.shape_link, np.int64),
            array(hand.shape_rot, np.float64),
            array(hand.shape_pos, np.float64),
            array(hand.shape_kind, np.int64),
            array(hand.shape_size, np.float64),
            array(spheres.shape_gap, np.float64),
            array(term.object_points, np.float32),
            *cluster_arrays(clusters, term.object_points),
            LEAVES_PER_PARENT,
        )

    def __call__(self, frames, object_index: torch.Tensor, scale: torch.Tensor, count: torch.Tensor, weight: torch.Tensor):
        """(energy (B,) attached to the frames' graph, object-in-hand max (B,), hand-in-object max (B,)), in metres."""
        rotation, translation = frame_arrays(frames)
        energy, object_max, hand_max, grad_rotation, grad_translation = _penetration_batch(
            rotation,
            translation,
            object_index.numpy().astype(np.int64, copy=False),
            scale.detach().numpy().astype(np.float64),
            count.numpy().astype(np.int64, copy=False),
            weight.detach().numpy().astype(np.float64),
            wants_gradient(frames),
            self.initial_hits,
            tuple(self.static),  # a plain tuple: numba's cache then names no class of this module
        )
        dtype = frames.rotation.dtype
        return attach(frames, energy, grad_rotation, grad_translation), torch.from_numpy(object_max).to(dtype), torch.from_numpy(hand_max).to(dtype)
