"""Ranking grasps by a score: how well it separates held from failed grasps, and the best distinct grasps per object.

``roc_auc`` and ``precision_at_fraction`` measure a score (the learned evaluator's, ``model.evaluator``)
against simulated outcomes; ``rank_distinct`` keeps the best-scored grasps of each object without two
that are the same grasp, so ranking does not trade diversity for score.
"""

from __future__ import annotations

import math

import numpy as np

from dexlite_pipeline.evaluation.diversity import distinct_grasp_labels, first_of_each_cluster
from dexlite_pipeline.model.score_metrics import roc_auc

__all__ = ["precision_at_fraction", "rank_distinct", "roc_auc"]  # roc_auc lives in model.score_metrics: the evaluator's training reports it


def precision_at_fraction(scores: np.ndarray, labels: np.ndarray, fraction: float) -> float:
    """Share of positives among the ceil(fraction * N) best-scored grasps (at least one).

    Scores tied across the cut count at their group's positive rate (the expectation over tie orders).
    """
    scores = np.asarray(scores, dtype=np.float64).reshape(-1)
    labels = np.asarray(labels, dtype=bool).reshape(-1)
    if len(scores) == 0:
        return float("nan")
    scores = np.nan_to_num(scores, nan=-np.inf)
    take = min(len(scores), max(1, math.ceil(fraction * len(scores))))
    threshold = np.sort(scores)[::-1][take - 1]
    above = scores > threshold
    tied = scores == threshold
    positives = labels[above].sum() + (take - above.sum()) * labels[tied].mean()
    return float(positives / take)


def rank_distinct(
    scores: np.ndarray, hand_pose: np.ndarray, object_index: np.ndarray, keep_per_object: int,
    translation_m: float = 0.02, rotation_deg: float = 30.0, fill: bool = False,
) -> np.ndarray:
    """Indices of at most ``keep_per_object`` best-scored grasps per object, no two of one object the same grasp.

    "The same grasp" is the project's distinct-grasp rule (``evaluation.diversity``): palms within
    ``translation_m`` (m) and ``rotation_deg`` (deg). Grasps are clustered in descending score
    order, so each cluster's representative is its best-scored grasp, and representatives are
    pairwise distinct. With ``fill``, an object with fewer distinct grasps than ``keep_per_object``
    is topped up with its best-scored remaining grasps (so every object keeps as many as it has, up
    to ``keep_per_object``). Returned in descending score order (ties: lower index first; NaN scores last).
    """
    scores = np.asarray(scores, dtype=np.float64).reshape(-1)
    order = np.argsort(-np.nan_to_num(scores, nan=-np.inf), kind="stable")
    groups = np.asarray(object_index)[order]
    labels = distinct_grasp_labels(np.asarray(hand_pose)[order], groups, translation_m, rotation_deg)
    kept, per_object = [], {}
    for position in first_of_each_cluster(labels):
        key = str(groups[position])
        if per_object.get(key, 0) < keep_per_object:
            per_object[key] = per_object.get(key, 0) + 1
            kept.append(order[position])
    if fill:
        chosen = set(kept)
        for position in range(len(order)):
            key = str(groups[position])
            if order[position] not in chosen and per_object.get(key, 0) < keep_per_object:
                per_object[key] = per_object.get(key, 0) + 1
                kept.append(order[position])
        rank = np.empty(len(order), np.int64)
        rank[order] = np.arange(len(order))
        kept.sort(key=lambda index: rank[index])
    return np.asarray(kept, dtype=np.int64)
