"""The learning ladder's metrics on known cases: pose errors, rungs, budget curve, convergence ratio."""

import math

import numpy as np
import pytest
import torch

from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix, matrix_to_euler_xyz
from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.model.pose import pose_errors
from dexlite_pipeline.evaluation.config import EvaluateConfig
from dexlite_pipeline.evaluation.convergence import convergence_ratio
from dexlite_pipeline.evaluation.protocol import BUDGET_SUCCESS
from dexlite_pipeline.evaluation.tables import budget_rows, metrics_tables, rung_of


def _poses(count: int, seed: int = 0) -> torch.Tensor:
    rng = np.random.default_rng(seed)
    pose = np.concatenate([rng.normal(0, 0.1, (count, 3)), rng.uniform(-3, 3, (count, 3)), rng.uniform(0, 1, (count, 22))], axis=1)
    return torch.as_tensor(pose, dtype=torch.float32)


def test_pose_errors_of_known_offsets():
    target = _poses(4)
    rotation, translation, joints = pose_errors(target, target)
    assert rotation.max() < 0.05 and translation.max() < 1e-4 and joints.max() == 0
    moved = target.clone()
    turn = torch.deg2rad(torch.tensor(10.0))
    about_z = torch.tensor([[turn.cos(), -turn.sin(), 0.0], [turn.sin(), turn.cos(), 0.0], [0.0, 0.0, 1.0]])
    moved[:, 3:6] = matrix_to_euler_xyz(about_z @ euler_xyz_to_matrix(target[:, 3:6]))  # 10° about the object's z
    moved[:, :3] += torch.tensor([0.003, 0.0, 0.004])  # 5 mm
    moved[:, 6:] += 0.1
    rotation, translation, joints = pose_errors(moved, target)
    np.testing.assert_allclose(rotation.numpy(), 10.0, atol=0.05)
    np.testing.assert_allclose(translation.numpy(), 5.0, atol=1e-3)
    np.testing.assert_allclose(joints.numpy(), 0.1, atol=1e-6)


def test_rungs_of_methods_and_splits():
    assert rung_of("cvae_recon", "train") == rung_of("cvae_recon_post", "train") == "fit"
    assert rung_of("cvae_prior_train", "train") == rung_of("cvae_prior_train_post", "train") == "in_distribution"
    assert rung_of("cvae_post", "heldout") == rung_of("random_post", "heldout") == "heldout"
    assert rung_of("optimization", "heldout") == "" and rung_of("cvae_raw", "train") == ""
    cfg = EvaluateConfig(splits=("heldout",))
    assert cfg.splits_of("cvae_recon") == ("train",) and cfg.splits_of("cvae_raw") == ("heldout",)
    assert cfg.cap_of("cvae_prior_train") == cfg.ladder_grasps_per_object and cfg.cap_of("optimization") == cfg.grasps_per_object


def test_metrics_rows_carry_rungs_and_ladder_rows_use_the_training_split():
    count = 6
    methods = np.array(["cvae_recon"] * 3 + ["cvae_raw"] * 3, dtype=object)
    splits = np.array(["train"] * 3 + ["heldout"] * 3, dtype=object)
    simulated = GraspSet({
        "hand_pose": _poses(count).numpy(), "object_id": np.array(["a", "b", "a", "c", "c", "d"], dtype=object),
        "scale": np.full(count, 0.1, np.float32), "method": methods, "split": splits,
        "lift_success": np.array([1, 1, 0, 0, 1, 0], bool), "six_dir_success": np.array([1, 0, 0, 0, 0, 0], bool),
        "invalid_reason": np.full(count, "", dtype=object),
        "fit_rotation_error_deg": np.array([1.0, 2.0, 9.0, np.nan, np.nan, np.nan]),
        "fit_translation_error_mm": np.array([3.0, 4.0, 5.0, np.nan, np.nan, np.nan]),
        "fit_joint_error_rad": np.array([0.1, 0.2, 0.6, np.nan, np.nan, np.nan]),
    })
    cfg = EvaluateConfig(methods=("cvae_raw", "cvae_recon"), splits=("heldout",))
    table, _ = metrics_tables(simulated, np.tile([0.0, 1.5], (22, 1)), cfg, {}, {})
    rows = {r.method: r for r in table.itertuples()}
    assert rows["cvae_recon"].split == "train" and rows["cvae_recon"].rung == "fit"
    assert rows["cvae_recon"].lift_success_rate == pytest.approx(2 / 3) and rows["cvae_recon"].six_dir_success_rate == pytest.approx(1 / 3)
    assert rows["cvae_recon"].fit_rotation_error_deg_median == 2.0 and rows["cvae_recon"].fit_translation_error_mm_median == 4.0
    assert rows["cvae_recon"].fit_joint_error_rad_mean == pytest.approx(0.3)
    assert math.isnan(rows["cvae_raw"].fit_rotation_error_deg_median)
    assert rows["cvae_raw"].split == "heldout" and rows["cvae_raw"].rung == "heldout" and rows["cvae_raw"].lift_success_rate == pytest.approx(1 / 3)


def test_budget_rows_skip_methods_without_a_curve():
    success = np.array([[0, 0, 1], [0, 1, 1], [np.nan, np.nan, np.nan], [0, 0, 0]], dtype=float)
    simulated = GraspSet({
        "hand_pose": _poses(4).numpy(), "object_id": np.array(list("abcd"), dtype=object), "scale": np.full(4, 0.1, np.float32),
        "method": np.array(["cvae_post", "cvae_post", "optimization", "random_post"], dtype=object), BUDGET_SUCCESS: success,
    })
    rows = budget_rows(simulated, [0, 100, 200], ("cvae_post", "random_post", "optimization"))
    got = {(r["method"], r["iteration"]): r["lift_success_rate"] for r in rows}
    assert got == {("cvae_post", 0): 0.0, ("cvae_post", 100): 0.5, ("cvae_post", 200): 1.0,
                   ("random_post", 0): 0.0, ("random_post", 100): 0.0, ("random_post", 200): 0.0}
    assert all(r["lift_ci95_low"] <= r["lift_success_rate"] <= r["lift_ci95_high"] for r in rows)


def test_convergence_ratio():
    assert convergence_ratio(200, 50) == 4.0
    assert convergence_ratio(200, 0) == 200.0  # a start already at random init's final level
    assert math.isnan(convergence_ratio(200, math.nan)) and math.isnan(convergence_ratio(math.nan, 10))
