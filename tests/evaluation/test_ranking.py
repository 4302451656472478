"""Ranking metrics and distinct ranking (evaluation.ranking): hand-computed cases, ties, near-duplicates."""

from __future__ import annotations

import numpy as np

from dexlite_pipeline.evaluation.ranking import precision_at_fraction, rank_distinct, roc_auc


def test_roc_auc_matches_hand_computed_cases():
    assert roc_auc([0.1, 0.2, 0.8, 0.9], [0, 0, 1, 1]) == 1.0
    assert roc_auc([0.9, 0.8, 0.2, 0.1], [0, 0, 1, 1]) == 0.0
    assert roc_auc([0.1, 0.4, 0.35, 0.8], [0, 0, 1, 1]) == 0.75  # one of four pairs misordered
    assert roc_auc([0.5, 0.5, 0.2, 0.9], [1, 0, 0, 1]) == 0.875  # the tied pair counts one half: 3.5 / 4
    assert roc_auc([0.3, 0.3, 0.3], [1, 0, 1]) == 0.5
    assert np.isnan(roc_auc([0.1, 0.2], [1, 1]))


def test_precision_at_fraction_with_and_without_ties():
    scores, labels = [0.9, 0.8, 0.7, 0.1], [1, 0, 1, 0]
    assert precision_at_fraction(scores, labels, 0.25) == 1.0
    assert precision_at_fraction(scores, labels, 0.5) == 0.5
    assert precision_at_fraction(scores, labels, 1.0) == 0.5
    # the second place is a tie of one positive and one negative: expected 1 + 0.5 positives in the top 2
    assert precision_at_fraction([0.9, 0.5, 0.5, 0.1], [1, 1, 0, 0], 0.5) == 0.75


def test_rank_distinct_keeps_the_best_of_near_duplicates_and_never_two():
    from dexlite_pipeline.evaluation.diversity import palm_rotations

    base = np.zeros((6, 28), np.float32)
    base[1, :3] = [0.01, 0.0, 0.0]  # 1 cm and 10 deg from grasp 0: the same grasp
    base[1, 3] = np.deg2rad(10.0)
    base[2, :3] = [0.0, 0.015, 0.0]  # 1.5 cm from grasp 0: the same grasp
    base[3, :3] = [0.05, 0.0, 0.0]  # 5 cm away: distinct
    base[4, 3] = np.deg2rad(60.0)  # same place, turned 60 deg: distinct
    base[5] = base[0]  # identical pose on another object: distinct (other object)
    scores = np.array([0.6, 0.9, 0.5, 0.2, 0.4, 0.1])
    objects = np.array(["a", "a", "a", "a", "a", "b"])
    kept = rank_distinct(scores, base, objects, keep_per_object=10)
    assert kept.tolist() == [1, 4, 3, 5]  # grasp 1 represents {0, 1, 2}; descending score
    rotations = palm_rotations(base)
    for i in kept:
        for j in kept:
            if i < j and objects[i] == objects[j]:
                near = np.linalg.norm(base[i, :3] - base[j, :3]) <= 0.02
                angle = np.degrees(np.arccos(np.clip((np.trace(rotations[i].T @ rotations[j]) - 1) / 2, -1, 1)))
                assert not (near and angle <= 30.0)
    assert rank_distinct(scores, base, objects, keep_per_object=1).tolist() == [1, 5]


def test_rank_distinct_fill_tops_up_with_the_best_remaining_grasps():
    base = np.zeros((6, 28), np.float32)
    base[1, :3] = [0.01, 0.0, 0.0]
    base[1, 3] = np.deg2rad(10.0)
    base[2, :3] = [0.0, 0.015, 0.0]
    base[3, :3] = [0.05, 0.0, 0.0]
    base[4, 3] = np.deg2rad(60.0)
    base[5] = base[0]
    scores = np.array([0.6, 0.9, 0.5, 0.2, 0.4, 0.1])
    objects = np.array(["a", "a", "a", "a", "a", "b"])
    # three distinct grasps on "a" (1, 4, 3); a fourth slot takes the best of the rest (0), in descending score
    assert rank_distinct(scores, base, objects, keep_per_object=4, fill=True).tolist() == [1, 0, 4, 3, 5]
    assert rank_distinct(scores, base, objects, keep_per_object=4).tolist() == [1, 4, 3, 5]
    assert rank_distinct(scores, base, objects, keep_per_object=9, fill=True).tolist() == [1, 0, 2, 4, 3, 5]
    assert rank_distinct(scores, base, objects, keep_per_object=2, fill=True).tolist() == [1, 4, 5]  # distinct first
