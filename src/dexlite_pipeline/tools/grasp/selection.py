"""Distinct grasps among the held ones: the rank of grasps (best first), the distinct-grasp label of each held
grasp (``evaluation.diversity``, config section ``diversity``) and the best grasp of each label."""

from __future__ import annotations

from collections import Counter
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.settings import PipelineConfig


def grasp_rank(grasps: GraspSet) -> np.ndarray:
    """Row order best first: held, six-direction passed, more of the six directions passed, lower energy."""
    arrays = grasps.arrays
    n = len(grasps)
    held = np.asarray(arrays.get("lift_success", np.zeros(n, bool)), bool)
    six = np.asarray(arrays.get("six_dir_success", np.zeros(n, bool)), bool)
    passed = np.asarray(arrays["six_dir_passed"], bool).reshape(n, -1).sum(axis=1) if "six_dir_passed" in arrays else np.zeros(n)
    energy = np.full(n, np.inf)
    for name in ("E_total", "E_post"):  # a model grasp's post-optimization energy, else the optimizer's (rows of both sources)
        if name in arrays:
            values = np.asarray(arrays[name], np.float64)
            energy = np.where(np.isfinite(values), values, energy)
    return np.lexsort((np.arange(n), energy, -passed, ~six, ~held))


def distinct_labels(grasps: GraspSet, config: PipelineConfig) -> np.ndarray:
    """(N,) distinct-grasp label of each held grasp (clusters of one object and scale, best grasp first), -1 if not held."""
    from dexlite_pipeline.evaluation.diversity import distinct_grasp_labels

    held = np.asarray(grasps.arrays["lift_success"], bool)
    labels = np.full(len(grasps), -1, dtype=np.int64)
    order = [i for i in grasp_rank(grasps) if held[i]]
    if order:
        groups = np.asarray([f"{grasps.object_id[i]}@{float(grasps.scale[i]):.6g}" for i in order])
        labels[order] = distinct_grasp_labels(
            grasps.hand_pose[order], groups, config.diversity.distinct_translation_m, config.diversity.distinct_rotation_deg
        )
    return labels


def representatives(grasps: GraspSet, labels: np.ndarray) -> np.ndarray:
    """Rows of the best grasp of each distinct-grasp cluster, best first (clusters are numbered best first)."""
    order = [i for i in grasp_rank(grasps) if labels[i] >= 0]
    seen: set[int] = set()
    rows = []
    for i in order:
        if labels[i] not in seen:
            seen.add(int(labels[i]))
            rows.append(i)
    return np.asarray(rows, dtype=np.int64)


def distinct_per_object(grasps: GraspSet, labels: np.ndarray) -> Counter:
    """Object id -> number of distinct held grasps (labels from ``distinct_labels``; objects with none are absent)."""
    held = labels >= 0
    return Counter(str(o) for o, _ in set(zip(grasps.object_id[held].tolist(), labels[held].tolist())))


def kept_rows(grasps: GraspSet, labels: np.ndarray, distinct_only: bool) -> np.ndarray:
    """Rows that ``grasps.zarr`` keeps, in row order: the best grasp of each distinct-grasp cluster, or every held
    grasp when ``distinct_only`` is false (labels from ``distinct_labels``: -1 for a grasp that did not hold)."""
    return np.sort(representatives(grasps, labels) if distinct_only else np.flatnonzero(labels >= 0))
