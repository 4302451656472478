"""Metric functions on cases with known answers."""

import math

import numpy as np
import pytest

from dexlite_pipeline.evaluation import convergence, metrics, rates

LIMITS = np.tile(np.array([[0.0, 1.0]]), (22, 1))


def test_rate_one_in_four():
    assert rates.rate(np.array([True, False, False, False])) == 0.25
    assert math.isnan(rates.rate(np.array([], dtype=bool)))


def test_wilson_interval_known_values():
    low, high = rates.wilson_interval(np.array([True] * 5 + [False] * 5))
    assert (low, high) == (pytest.approx(0.2366, abs=1e-4), pytest.approx(0.7634, abs=1e-4))
    low, high = rates.wilson_interval(np.zeros(10, dtype=bool))
    assert low == 0.0 and high == pytest.approx(0.2775, abs=1e-4)  # not degenerate at zero successes
    low, high = rates.wilson_interval(np.ones(80, dtype=bool))
    assert high == pytest.approx(1.0) and low == pytest.approx(0.9542, abs=1e-4)
    assert all(math.isnan(v) for v in rates.wilson_interval(np.array([], dtype=bool)))


def test_object_success_rate_counts_objects_with_any_success():
    ids = np.array(["a", "a", "b", "b", "c"])
    success = np.array([False, True, False, False, False])
    assert rates.object_success_rate(ids, success) == pytest.approx(1 / 3)


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
    first = convergence.first_iteration_meeting(traces)
    assert first.tolist() == [2, -1]
    summary = convergence.convergence_summary(first, iteration_of_column=np.array([0, 10, 20, 30]))
    assert summary == {"threshold_reached_fraction": 0.5, "threshold_iteration_median": 20.0}


def test_trace_quartiles():
    trace = np.tile(np.arange(5.0)[:, None], (1, 3))  # grasps 0..4 at every iteration
    q = convergence.trace_quartiles(trace)
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
        "filter_E_fc": np.array([0.1, 0.2, 0.3, 0.4]),  # the filter's energies (its contact search)
        "filter_E_dis": np.array([0.001, 0.001, 0.01, 0.001]),
        "E_pen": np.zeros(n),
        "initial_penetration_mm": np.array([0.7, 3.0, np.nan, 1.0]),
    }
    out = metrics.summarize_grasps(arrays, LIMITS, entropy_bins=4)
    assert out["held_start_depth_median_mm"] == pytest.approx(0.7) and out["held_start_depth_p90_mm"] == pytest.approx(0.7)  # the one held grasp
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
    wilson = rates.wilson_interval(flags)
    low, high = rates.cluster_bootstrap_interval(ids, flags, seed=0)
    assert wilson == (pytest.approx(0.300, abs=1e-3), pytest.approx(0.510, abs=1e-3))
    assert low <= 0.05 and high >= 0.75
    assert high - low > 3 * (wilson[1] - wilson[0])
    assert (low, high) == rates.cluster_bootstrap_interval(ids, flags, seed=0)  # seeded: the same interval again


def test_cluster_bootstrap_collapses_when_every_object_has_the_same_rate():
    ids, flags = _clustered([0.25] * 5)
    assert rates.cluster_bootstrap_interval(ids, flags, seed=0) == (pytest.approx(0.25), pytest.approx(0.25))
    assert all(math.isnan(v) for v in rates.cluster_bootstrap_interval(np.array([]), np.array([], dtype=bool), seed=0))


def test_summary_has_bootstrap_columns_beside_wilson():
    ids, flags = _clustered([1, 1, 0, 0, 0])
    arrays = {"hand_pose": np.zeros((len(ids), 28)), "object_id": ids, "lift_success": flags}
    out = metrics.summarize_grasps(arrays, LIMITS, bootstrap_seed=0)
    assert (out["lift_success_boot_ci95_low"], out["lift_success_boot_ci95_high"]) == rates.cluster_bootstrap_interval(ids, flags, seed=0)
    assert out["lift_success_ci95_high"] < out["lift_success_boot_ci95_high"]
    assert math.isnan(out["six_dir_success_boot_ci95_low"])  # not measured: no interval either


def _held_table():
    """Six attempts of one method on two objects, with known held grasps, palms, energies and touched patches.

    Object a: three held grasps, two identical and one 3 cm away (2 distinct); object b: one held, one dropped.
    The energy filter passes a0, a1 (identical), b0 and b1; a2 fails E_fc. Four surface patches per object.
    """
    pose = np.zeros((6, 28))
    pose[:, 2] = 0.1
    pose[2, 0] = 0.03  # a2: 3 cm from a0 and a1
    pose[4, 1] = 0.05  # b1
    touched = np.zeros((6, 4), bool)
    for row, patches in ((0, [0]), (1, [0]), (2, [1]), (3, [2, 3]), (4, [0, 1])):
        touched[row, patches] = True
    return {
        "hand_pose": pose,
        "object_id": np.array(["a", "a", "a", "b", "b", "b"], dtype=object),
        "scale": np.full(6, 0.1),
        "lift_success": np.array([True, True, True, True, False, False]),
        "six_dir_success": np.array([True, False, True, False, False, False]),
        "E_fc": np.full(6, 2.0),  # the nearest-four contacts' energies: not what the filter reads
        "E_dis": np.full(6, 0.001),
        "filter_E_fc": np.array([0.1, 0.1, 0.5, 0.1, 0.1, np.nan]),
        "filter_E_dis": np.full(6, 0.001),
        "E_pen": np.zeros(6),
        "penetration_mm": np.full(6, 0.5),
        "invalid_reason": np.array(["", "", "", "", "", "non-finite hand_pose"], dtype=object),
        metrics.TOUCHED_PATCHES: touched,
        metrics.COVERAGE_PATCHES: np.full(6, 4),
    }


def test_rows_carry_distinct_held_grasps_coverage_and_the_equal_filter():
    out = metrics.summarize_grasps(_held_table(), LIMITS, entropy_bins=4)
    # per attempt: 4 held; a: identical grasps once, 3 cm apart twice -> 2; b: 1
    assert (out["n_held"], out["distinct_held_total"], out["distinct_held_per_object_mean"]) == (4, 3, 1.5)
    assert out["distinct_held_per_attempt"] == pytest.approx(3 / 6)
    assert out["surface_coverage_mean"] == pytest.approx((2 / 4 + 2 / 4) / 2)  # a: patches 0, 1; b: 2, 3 (b1 dropped)
    # the filter: a2 fails E_fc, the invalid grasp passes nothing -> 4 of 6 pass; 3 of them held
    assert out["energy_threshold_pass_rate"] == pytest.approx(4 / 6) and out["filtered_n_grasps"] == 4
    assert out["filtered_lift_success_rate"] == pytest.approx(3 / 4) and out["filtered_six_dir_success_rate"] == pytest.approx(1 / 4)
    assert out["filtered_lift_success_ci95_low"] < 0.75 < out["filtered_lift_success_ci95_high"]
    assert (out["filtered_n_held"], out["filtered_distinct_held_total"], out["filtered_distinct_held_per_object_mean"]) == (3, 2, 1.0)
    assert out["filtered_surface_coverage_mean"] == pytest.approx((1 / 4 + 2 / 4) / 2)
    rows = {r["object_id"]: r for r in metrics.per_object_rows(_held_table())}
    assert [rows["a"][k] for k in ("n_held", "n_distinct_held", "surface_coverage")] == [3, 2, 0.5]
    assert [rows["b"][k] for k in ("n_held", "n_distinct_held", "surface_coverage")] == [1, 1, 0.5]
    assert [rows["a"][k] for k in ("filtered_n_grasps", "filtered_n_held", "filtered_n_distinct_held", "filtered_surface_coverage")] == [2, 2, 1, 0.25]
    assert [rows["b"][k] for k in ("filtered_n_grasps", "filtered_n_held", "filtered_n_distinct_held")] == [2, 1, 1]


def test_distinct_grasps_of_other_scales_are_other_grasps():
    table = _held_table()
    table["scale"] = np.array([0.1, 0.12, 0.1, 0.1, 0.1, 0.1])  # a1: the same palm pose on the object at another size
    assert metrics.summarize_grasps(table, LIMITS, entropy_bins=4)["distinct_held_total"] == 4


def test_filter_thresholds_are_a_setting():
    strict = metrics.summarize_grasps(_held_table(), LIMITS, entropy_bins=4, thresholds={"E_fc": 0.05, "E_dis": 0.005, "E_pen": 0.001})
    assert strict["energy_threshold_pass_rate"] == 0.0 and strict["filtered_n_grasps"] == 0 and math.isnan(strict["filtered_lift_success_rate"])
    assert strict["filtered_distinct_held_total"] == 0


def test_without_energies_or_patches_the_columns_are_nan_not_zero():
    table = {k: v for k, v in _held_table().items() if k not in ("filter_E_fc", metrics.TOUCHED_PATCHES)}
    out = metrics.summarize_grasps(table, LIMITS, entropy_bins=4)
    assert out["distinct_held_total"] == 3  # needs only poses and outcomes
    for column in ("surface_coverage_mean", "energy_threshold_pass_rate", "filtered_lift_success_rate", "filtered_distinct_held_total"):
        assert math.isnan(out[column]), column


def test_seconds_per_outcome():
    assert metrics.seconds_per_outcome(2.0, 6, 4) == 3.0
    assert metrics.seconds_per_outcome(2.0, 6, 0) == math.inf
    assert math.isnan(metrics.seconds_per_outcome(math.nan, 6, 4)) and math.isnan(metrics.seconds_per_outcome(2.0, 0, 0))


def test_metrics_tables_give_cost_per_held_and_distinct_held_grasp_for_every_method():
    """Two methods, the same synthetic table: each has both per-attempt and after-filter columns (none filtered alone)."""
    from dexlite_pipeline.evaluation.config import EvaluateConfig
    from dexlite_pipeline.evaluation.tables import metrics_tables
    from dexlite_pipeline.io.grasp_store import GraspSet

    one = _held_table()
    both = {k: np.concatenate([v, v]) for k, v in one.items()}
    both["method"] = np.array(["optimization"] * 6 + ["cvae_post"] * 6, dtype=object)
    both["split"] = np.full(12, "heldout", dtype=object)
    cfg = EvaluateConfig(methods=("optimization", "cvae_post"), entropy_bins=4)
    table, per_object = metrics_tables(GraspSet(both), LIMITS, cfg, {"optimization": {"optimized": 2.0}, "cvae_post": {"sample": 0.5, "post": 1.5}}, {})
    table = table.set_index("method")
    for method in ("optimization", "cvae_post"):
        row = table.loc[method]
        assert row["seconds_per_grasp"] == 2.0 and row["lift_success_rate"] == pytest.approx(4 / 6)
        assert row["filtered_lift_success_rate"] == pytest.approx(3 / 4)
        assert row["cpu_seconds_per_held_grasp"] == pytest.approx(12 / 4)  # 6 attempts x 2 s over 4 held
        assert row["cpu_seconds_per_distinct_held_grasp"] == pytest.approx(12 / 3)
        assert row["filtered_cpu_seconds_per_held_grasp"] == pytest.approx(12 / 3)
        assert row["filtered_cpu_seconds_per_distinct_held_grasp"] == pytest.approx(12 / 2)
    assert per_object.groupby("method")["n_distinct_held"].sum().to_dict() == {"cvae_post": 3, "optimization": 3}
    assert {"n_held", "n_distinct_held", "surface_coverage", "filtered_n_held", "filtered_surface_coverage"} <= set(per_object.columns)
