"""Distinct labels of held grasps, consistent over the whole dataset.

The project's rule (``evaluation.diversity``): two grasps of the same object and scale are one
grasp when their palms are within ``DISTINCT_TRANSLATION_M`` (0.02 m) and ``DISTINCT_ROTATION_DEG``
(30 deg); grasps of different scales are never one grasp. Labels are numbered per object (0, 1, ...
over all its scales), so an object's count of distinct held grasps is its number of labels.

A label is represented by its first grasp in dataset order (batch, then row). A new held grasp
gets the label of the first representative of its object and scale that it matches, else a new
label (the object's largest label + 1); grasps of the same batch are taken in row order, so a new
label's first grasp represents it for the grasps after it. This is ``distinct_grasp_labels``' greedy
clustering with the representatives first, so labels never change once given, and adding the same
batches in the same order always gives the same labels. Grasps that were not held get -1.
"""

from __future__ import annotations

import numpy as np

from dexlite_pipeline.dataset.layout import DISTINCT_ROTATION_DEG, DISTINCT_TRANSLATION_M, NOT_HELD_LABEL
from dexlite_pipeline.evaluation.diversity import distinct_grasp_labels


def object_scale_keys(object_id: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Per grasp, "<object_id>|<scale>" (the float32 scale in its shortest text): the groups one grasp can belong to."""
    scale_text = [str(s) for s in np.asarray(scale, dtype=np.float32)]
    return np.asarray([f"{o}|{s}" for o, s in zip(np.asarray(object_id).astype(str), scale_text)], dtype=object)


def representatives(object_id: np.ndarray, label: np.ndarray) -> np.ndarray:
    """Indices of the first grasp of each (object, label >= 0), in label order per object (dataset order given)."""
    object_id = np.asarray(object_id).astype(str)
    label = np.asarray(label, dtype=np.int64)
    first: dict[tuple[str, int], int] = {}
    for index in np.flatnonzero(label >= 0):
        first.setdefault((object_id[index], int(label[index])), int(index))
    return np.asarray([first[key] for key in sorted(first)], dtype=np.int64)


def assign_distinct_labels(
    known_object_id: np.ndarray,
    known_scale: np.ndarray,
    known_pose: np.ndarray,
    known_label: np.ndarray,
    new_object_id: np.ndarray,
    new_scale: np.ndarray,
    new_pose: np.ndarray,
    new_held: np.ndarray,
) -> tuple[np.ndarray, int]:
    """(labels (M,) int32 of the new grasps, number of new labels) given the dataset's labelled grasps.

    ``known_*``: the dataset's grasps (at least the held ones of the new grasps' objects) in dataset
    order with their labels (-1: not held). ``new_held`` (M,) bool: which new grasps were held.
    """
    new_object_id = np.asarray(new_object_id).astype(str)
    labels = np.full(len(new_object_id), NOT_HELD_LABEL, dtype=np.int32)
    held_rows = np.flatnonzero(np.asarray(new_held, dtype=bool))
    if held_rows.size == 0:
        return labels, 0
    known_object_id = np.asarray(known_object_id).astype(str)
    known_label = np.asarray(known_label, dtype=np.int64)
    reps = representatives(known_object_id, known_label)
    next_label: dict[str, int] = {}
    for object_id, label in zip(known_object_id[reps], known_label[reps]):
        next_label[object_id] = max(next_label.get(object_id, 0), int(label) + 1)

    width = np.asarray(new_pose).shape[1]  # 6 + J numbers of the batch's hand (the dataset's: one hand per dataset)
    poses = np.concatenate([np.asarray(known_pose, np.float64).reshape(-1, width)[reps], np.asarray(new_pose, np.float64)[held_rows]])
    groups = np.concatenate([object_scale_keys(known_object_id[reps], np.asarray(known_scale)[reps]),
                             object_scale_keys(new_object_id[held_rows], np.asarray(new_scale)[held_rows])])  # fmt: skip
    clusters = distinct_grasp_labels(poses, groups, DISTINCT_TRANSLATION_M, DISTINCT_ROTATION_DEG)
    # A cluster's first member comes first in ``poses``: a representative when the cluster has one.
    label_of_cluster: dict[int, int] = {}
    for cluster, rep in zip(clusters[: len(reps)], reps):
        label_of_cluster.setdefault(int(cluster), int(known_label[rep]))
    added = 0
    for cluster, row in zip(clusters[len(reps):], held_rows):
        cluster = int(cluster)
        if cluster not in label_of_cluster:
            object_id = new_object_id[row]
            label_of_cluster[cluster] = next_label.get(object_id, 0)
            next_label[object_id] = label_of_cluster[cluster] + 1
            added += 1
        labels[row] = label_of_cluster[cluster]
    return labels, added
