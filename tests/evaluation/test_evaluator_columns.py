"""The evaluation's columns on the learned evaluator's score: AUC, held rate at the kept share, calibration."""

from __future__ import annotations

import math

import numpy as np

from dexlite_pipeline.evaluation.tables import evaluator_columns


def test_columns_measure_a_score_against_the_outcomes():
    score = np.array([0.9, 0.8, 0.7, 0.3, 0.2, 0.1, np.nan, 0.5], np.float32)
    held = np.array([True, True, False, True, False, False, True, False])
    subset = {"evaluator_score": score, "lift_success": held, "six_dir_success": held & (score > 0.75),
              "evaluator_kept_fraction": np.full(8, 0.25, np.float32),
              "invalid_reason": np.array(["", "", "", "", "", "", "", "bad pose"], dtype=object)}
    out = evaluator_columns(subset)
    assert out["evaluator_scored"] == 6  # NaN score and the invalid grasp left out
    # positives 0.9, 0.8, 0.3; negatives 0.7, 0.2, 0.1: pairs won 3 + 3 + 2 = 8 of 9
    assert math.isclose(out["evaluator_auc_held"], 8 / 9)
    assert out["evaluator_auc_six_dir"] == 1.0
    assert out["evaluator_held_rate_at_kept"] == 1.0  # the best 2 of 6 (ceil 0.25 * 6) both held
    assert math.isclose(out["evaluator_held_rate_all"], 0.5)
    assert out["evaluator_calibration"].startswith("0.0-0.2: 0.10/0.00 (1)")
    assert "0.8-1.0: 0.85/1.00 (2)" in out["evaluator_calibration"]


def test_no_columns_without_scores():
    assert evaluator_columns({"lift_success": np.array([True])}) == {}
    assert evaluator_columns({"evaluator_score": np.array([np.nan]), "lift_success": np.array([True])}) == {}
