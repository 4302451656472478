"""Metric functions on cases with known answers."""

import math

import numpy as np
import pytest

from dexlite_pipeline.evaluation import metrics

LIMITS = np.tile(np.array([[0.0, 1.0]]), (22, 1))


def test_rate_one_in_four():
    assert metrics.rate(np.array([True, False, False, False])) == 0.25
    assert math.isnan(metrics.rate(np.array([], dtype=bool)))


def test_wilson_interval_known_values():
    low, high = metrics.wilson_interval(np.array([True] * 5 + [False] * 5))
    assert (low, high) == (pytest.approx(0.2366, abs=1e-4), pytest.approx(0.7634, abs=1e-4))
    low, high = metrics.wilson_interval(np.zeros(10, dtype=bool))
    assert low == 0.0 and high == pytest.approx(0.2775, abs=1e-4)  # not degenerate at zero successes
    low, high = metrics.wilson_interval(np.ones(80, dtype=bool))
    assert high == pytest.approx(1.0) and low == pytest.approx(0.9542, abs=1e-4)
    assert all(math.isnan(v) for v in metrics.wilson_interval(np.array([], dtype=bool)))


def test_object_success_rate_counts_objects_with_any_success():
    ids = np.array(["a", "a", "b", "b", "c"])
    success = np.array([False, True, False, False, False])
    assert metrics.object_success_rate(ids, success) == pytest.approx(1 / 3)


def test_mean_and_p95_ignore_non_finite():
    values = np.concatenate([np.arange(1, 101, dtype=float), [np.nan, np.inf]])
    mean, p95 = metrics.mean_and_p95(values)
    assert mean == pytest.approx(50.5)
    assert p95 == pytest.approx(np.percentile(np.arange(1, 101), 95))


def test_joint_entropy_identical_poses_is_zero_and_uniform_is_log2_bins():
    same = np.full((50, 22), 0.3)
    assert np.allclose(metrics.joint_entropy_bits(same, LIMITS, bins=10), 0.0)
    # one grasp in the centre of each of 10 bins: the maximum, log2(10) bits
    spread = np.tile(((np.arange(10) + 0.5) / 10)[:, None], (1, 22))
    assert np.allclose(metrics.joint_entropy_bits(spread, LIMITS, bins=10), math.log2(10))


def test_joint_entropy_uses_joint_limits_and_clips_outliers():
    joints = np.zeros((4, 22))
    joints[:2, 0] = -5.0  # below the range: clipped into the first bin
    joints[2:, 0] = 0.95  # last bin
    h = metrics.joint_entropy_bits(joints, LIMITS, bins=10)
    assert h[0] == pytest.approx(1.0)
    assert np.allclose(h[1:], 0.0)


def test_pca_on_a_line_is_one_component():
    rng = np.random.default_rng(0)
    direction = rng.normal(size=22)
    x = rng.normal(size=(200, 1)) * direction[None, :] + 0.5
    cev = metrics.pca_cumulative_explained_variance(x, (1, 3))
    assert cev[1] == pytest.approx(1.0, abs=1e-9)
    isotropic = metrics.pca_cumulative_explained_variance(rng.normal(size=(5000, 22)), (1, 22))
    assert isotropic[1] < 0.1 and isotropic[22] == pytest.approx(1.0)
    assert math.isnan(metrics.pca_cumulative_explained_variance(np.ones((10, 22)), (1,))[1])


def test_first_iteration_meeting_thresholds():
    traces = {
        "E_fc": np.array([[1.0, 0.2, 0.2, 0.2], [1.0, 1.0, 1.0, 1.0]]),
        "E_dis": np.array([[0.01, 0.01, 0.004, 0.001], [0.0, 0.0, 0.0, 0.0]]),
        "E_pen": np.array([[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]]),
    }
    first = metrics.first_iteration_meeting(traces)
    assert first.tolist() == [2, -1]
    summary = metrics.convergence_summary(first, iteration_of_column=np.array([0, 10, 20, 30]))
    assert summary == {"threshold_reached_fraction": 0.5, "threshold_iteration_median": 20.0}


def test_trace_quartiles():
    trace = np.tile(np.arange(5.0)[:, None], (1, 3))  # grasps 0..4 at every iteration
    q = metrics.trace_quartiles(trace)
    assert q.shape == (3, 3)
    assert np.allclose(q[:, 0], [1.0, 2.0, 3.0])


def test_summarize_grasps_columns():
    n = 4
    pose = np.zeros((n, 28))
    pose[:, 6:] = np.linspace(0, 1, n)[:, None]
    arrays = {
        "hand_pose": pose,
        "object_id": np.array(["a", "a", "b", "b"], dtype=object),
        "lift_success": np.array([True, False, False, False]),
        "six_dir_success": np.array([False, False, False, False]),
        "penetration_mm": np.array([1.0, 2.0, 3.0, 4.0]),
        "E_fc": np.array([0.1, 0.2, 0.3, 0.4]),
        "E_dis": np.array([0.001, 0.001, 0.01, 0.001]),
        "E_pen": np.zeros(n),
    }
    out = metrics.summarize_grasps(arrays, LIMITS, entropy_bins=4)
    assert out["lift_success_rate"] == 0.25
    assert out["object_success_rate"] == 0.5
    assert out["six_dir_success_rate"] == 0.0
    assert out["lift_success_ci95_low"] < 0.25 < out["lift_success_ci95_high"]
    assert out["six_dir_success_ci95_low"] == 0.0 and out["six_dir_success_ci95_high"] > 0.0
    assert out["penetration_mean_mm"] == pytest.approx(2.5)
    assert out["energy_threshold_pass_rate"] == 0.5  # grasp 2 fails E_fc (not < 0.3) and E_dis, grasp 3 fails E_fc
    assert out["joint_entropy_bits"] == pytest.approx(2.0)  # four values in four bins
    assert out["pca_explained_variance_k1"] == pytest.approx(1.0)
    assert math.isnan(out["contact_distance_mean_mm"])
    rows = metrics.per_object_rows(arrays)
    assert [r["lift_success_rate"] for r in rows] == [0.5, 0.0]


def test_invalid_grasps_fail_every_rate_and_are_left_out_of_diversity():
    pose = np.zeros((4, 28))
    pose[:, 6:] = np.linspace(0, 1, 4)[:, None]
    pose[3] = np.nan
    arrays = {
        "hand_pose": pose,
        "object_id": np.array(["a", "a", "b", "b"], dtype=object),
        "lift_success": np.array([True, True, False, False]),
        "six_dir_success": np.array([True, False, False, False]),
        "invalid_reason": np.array(["", "", "", "non-finite hand_pose"], dtype=object),
    }
    out = metrics.summarize_grasps(arrays, LIMITS, entropy_bins=4)
    assert (out["n_grasps"], out["n_invalid"]) == (4, 1)
    assert out["lift_success_rate"] == 0.5 and out["six_dir_success_rate"] == 0.25
    assert math.isfinite(out["joint_entropy_bits"]) and out["joint_entropy_bits"] == pytest.approx(math.log2(3))
    assert [r["n_invalid"] for r in metrics.per_object_rows(arrays)] == [0, 1]


def _clustered(rates_per_object, grasps_per_object=16):
    """Object ids and success flags: object k has round(rate_k * grasps_per_object) successes."""
    ids, flags = [], []
    for k, rate in enumerate(rates_per_object):
        successes = round(rate * grasps_per_object)
        ids += [f"obj{k}"] * grasps_per_object
        flags += [True] * successes + [False] * (grasps_per_object - successes)
    return np.array(ids), np.array(flags)


def test_cluster_bootstrap_is_wider_than_wilson_when_objects_decide_success():
    """80 grasps, 16 each from 5 objects, two of which always hold and three never: 40%.

    Wilson (grasps independent) says 30-51%; resampling objects says anything from 0% to 80%
    is plausible for another 5 objects, which is the honest answer.
    """
    ids, flags = _clustered([1, 1, 0, 0, 0])
    wilson = metrics.wilson_interval(flags)
    low, high = metrics.cluster_bootstrap_interval(ids, flags, seed=0)
    assert wilson == (pytest.approx(0.300, abs=1e-3), pytest.approx(0.510, abs=1e-3))
    assert low <= 0.05 and high >= 0.75
    assert high - low > 3 * (wilson[1] - wilson[0])
    assert (low, high) == metrics.cluster_bootstrap_interval(ids, flags, seed=0)  # seeded: the same interval again


def test_cluster_bootstrap_collapses_when_every_object_has_the_same_rate():
    ids, flags = _clustered([0.25] * 5)
    assert metrics.cluster_bootstrap_interval(ids, flags, seed=0) == (pytest.approx(0.25), pytest.approx(0.25))
    assert all(math.isnan(v) for v in metrics.cluster_bootstrap_interval(np.array([]), np.array([], dtype=bool), seed=0))


def test_summary_has_bootstrap_columns_beside_wilson():
    ids, flags = _clustered([1, 1, 0, 0, 0])
    arrays = {"hand_pose": np.zeros((len(ids), 28)), "object_id": ids, "lift_success": flags}
    out = metrics.summarize_grasps(arrays, LIMITS, bootstrap_seed=0)
    assert (out["lift_success_boot_ci95_low"], out["lift_success_boot_ci95_high"]) == metrics.cluster_bootstrap_interval(ids, flags, seed=0)
    assert out["lift_success_ci95_high"] < out["lift_success_boot_ci95_high"]
    assert math.isnan(out["six_dir_success_boot_ci95_low"])  # not measured: no interval either
