"""Distinct grasps: how many different grasps a set really holds.

A success rate cannot tell sixteen different grasps from one grasp returned sixteen times.
Two grasps of the same object and scale are *the same grasp* when their palms are within
``translation_m`` of each other (distance between palm origins, metres) **and** within
``rotation_deg`` (angle of the relative palm rotation, degrees); otherwise they are distinct.
Grasps are clustered greedily in the order given (callers pass the better grasps first, so a
cluster is represented by its best member): each grasp joins the first cluster whose
representative it matches, else it starts a new one. The number of clusters of an object is
its count of distinct grasps. Joint angles are not compared: a hand at the same palm pose with
other finger angles touches the object in the same place.

Surface coverage: the share of an object's surface patches that a set of grasps touches.
The patches are fixed per object from its stored surface samples (uniform over the area):
``coverage_patches`` centres chosen by farthest-point sampling, each sample belonging to its
nearest centre, so the patches are of about equal area and scale with the object (a sphere of
10 cm radius in 256 patches: patches ~2.5 cm across, about a finger pad). A grasp touches a
patch when one of the hand's contact candidates (the palmar finger points the energies choose
contacts from) lies within ``coverage_contact_m`` of the surface (|signed distance|) and its
nearest surface sample is in that patch. Coverage = touched patches / patches, in [0, 1].
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from dexlite_pipeline.evaluation.config import DiversityConfig


def palm_rotations(hand_pose: np.ndarray) -> np.ndarray:
    """(N, 3, 3) palm rotation matrices of (N, 28) hand poses (static-axis xyz Euler, R = Rz Ry Rx)."""
    return Rotation.from_euler("xyz", np.asarray(hand_pose, dtype=np.float64)[:, 3:6]).as_matrix()


def distinct_grasp_labels(
    hand_pose: np.ndarray,
    groups: np.ndarray | None = None,
    translation_m: float = DiversityConfig.distinct_translation_m,
    rotation_deg: float = DiversityConfig.distinct_rotation_deg,
) -> np.ndarray:
    """Cluster index (N,) of each grasp, numbered from 0 in order of first appearance.

    ``groups`` (N,) keys grasps that may share a cluster (an object id, or an (object, scale)
    string); grasps of different groups never do. ``None``: all grasps belong to one group. Only the palm's pose
    (columns 0-5) counts, so poses of any hand (6 + J numbers) are clustered alike.
    """
    poses = np.asarray(hand_pose, dtype=np.float64)
    poses = poses.reshape(-1, poses.shape[-1] if poses.ndim >= 2 else 28)  # (N, 28), or (N, 6 + J) for a hand from its MJCF
    n = len(poses)
    labels = np.full(n, -1, dtype=np.int64)
    if n == 0:
        return labels
    keys = np.zeros(n, dtype=np.int64) if groups is None else np.unique(np.asarray(groups).astype(str), return_inverse=True)[1]
    translations = poses[:, :3]
    rotations = palm_rotations(poses)
    # cos of the relative angle: (trace(Ra^T Rb) - 1) / 2 >= cos(threshold) means within the threshold
    min_cos = np.cos(np.deg2rad(rotation_deg))
    next_label = 0
    representatives: dict[int, list[int]] = {}
    for i in range(n):
        reps = representatives.setdefault(int(keys[i]), [])
        if reps:
            idx = np.asarray(reps)
            near = np.linalg.norm(translations[idx] - translations[i], axis=1) <= translation_m
            traces = np.einsum("kab,ab->k", rotations[idx], rotations[i])
            aligned = (traces - 1.0) / 2.0 >= min_cos - 1e-12
            match = np.flatnonzero(near & aligned)
            if match.size:
                labels[i] = labels[idx[match[0]]]
                continue
        labels[i] = next_label
        next_label += 1
        reps.append(i)
    return labels


def count_distinct_grasps(
    hand_pose: np.ndarray,
    translation_m: float = DiversityConfig.distinct_translation_m,
    rotation_deg: float = DiversityConfig.distinct_rotation_deg,
) -> int:
    """Number of distinct grasps among grasps of one object and scale."""
    labels = distinct_grasp_labels(hand_pose, None, translation_m, rotation_deg)
    return int(labels.max() + 1) if labels.size else 0


def first_of_each_cluster(labels: np.ndarray) -> np.ndarray:
    """Indices of the first grasp of each cluster (its representative), in cluster order."""
    labels = np.asarray(labels)
    if labels.size == 0:
        return np.zeros(0, dtype=np.int64)
    _, first = np.unique(labels, return_index=True)
    return np.sort(first)


def surface_patch_labels(surface_points: np.ndarray, patches: int) -> np.ndarray:
    """Patch index (P,) of each surface sample: nearest of ``patches`` farthest-point centres.

    Deterministic: the first centre is the sample farthest from the samples' centroid (lowest
    index on ties), each next one the sample farthest from the centres so far. With fewer
    samples than ``patches`` every sample is its own patch. Patch ids are 0..K-1, K = min(patches, P).
    """
    points = np.asarray(surface_points, dtype=np.float64).reshape(-1, 3)
    count = min(int(patches), len(points))
    if count == 0:
        return np.zeros(0, dtype=np.int64)
    centres = [int(np.argmax(np.linalg.norm(points - points.mean(axis=0), axis=1)))]
    nearest = np.linalg.norm(points - points[centres[0]], axis=1)
    for _ in range(count - 1):
        centres.append(int(np.argmax(nearest)))
        nearest = np.minimum(nearest, np.linalg.norm(points - points[centres[-1]], axis=1))
    centre_points = points[centres]
    return np.argmin(np.linalg.norm(points[:, None, :] - centre_points[None, :, :], axis=2), axis=1).astype(np.int64)


def touched_patches(
    contact_points: np.ndarray,
    contact_distance_m: np.ndarray,
    surface_points: np.ndarray,
    patch_labels: np.ndarray,
    contact_m: float = DiversityConfig.coverage_contact_m,
) -> np.ndarray:
    """(N, K) bool: which patches each grasp touches.

    ``contact_points`` (N, C, 3): the hand's contact candidates of N grasps in the frame of
    ``surface_points`` (P, 3); ``contact_distance_m`` (N, C): each candidate's distance to the
    surface in metres (sign ignored: a candidate pressed in by less than ``contact_m`` touches
    too). A candidate within ``contact_m`` touches the patch of its nearest surface sample.
    """
    from scipy.spatial import cKDTree

    labels = np.asarray(patch_labels, dtype=np.int64)
    count = int(labels.max()) + 1 if labels.size else 0
    points = np.asarray(contact_points, dtype=np.float64)
    n = points.shape[0]
    touched = np.zeros((n, count), dtype=bool)
    close = np.abs(np.asarray(contact_distance_m, dtype=np.float64)) <= contact_m  # NaN: not close
    if n == 0 or count == 0 or not close.any():
        return touched
    grasp, candidate = np.nonzero(close)
    _, nearest = cKDTree(np.asarray(surface_points, dtype=np.float64)).query(points[grasp, candidate])
    touched[grasp, labels[nearest]] = True
    return touched


def surface_coverage(touched: np.ndarray) -> float:
    """Share of patches touched by at least one of the grasps of ``touched`` (N, K); 0 with no grasps, NaN with no patches."""
    touched = np.asarray(touched, dtype=bool)
    if touched.ndim != 2 or touched.shape[1] == 0:
        return float("nan")
    return float(touched.any(axis=0).mean())
