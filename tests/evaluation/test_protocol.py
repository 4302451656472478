"""Evaluation stage pieces: grasp selection, aggregation to CSV, and the HTML report from a tiny run."""

import base64
import json
import re
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dexlite_pipeline.cli import main
from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.evaluation.config import EvaluateConfig
from dexlite_pipeline.evaluation.selection import method_grasps, sample_rows_of, select_grasps, stage_seconds_per_grasp
from dexlite_pipeline.evaluation.step_keys import METHOD_SOURCES

from report_synthetic import OBJECT_ID, post_store, simulated_shard


def _set(object_ids, extra=None):
    n = len(object_ids)
    arrays = {"hand_pose": np.zeros((n, 28), np.float32), "object_id": np.asarray(object_ids, dtype=object), "scale": np.full(n, 0.1, np.float32)}
    arrays.update(extra or {})
    return GraspSet(arrays)


def test_select_grasps_caps_per_object_keeps_split_and_keeps_invalid_as_chosen_rows():
    ids = ["a"] * 10 + ["b"] * 3 + ["t"] * 5
    grasps = _set(ids)
    grasps.arrays["scale"][10] = np.nan  # one of b's three: chosen whatever the draw (cap 4)
    split_of = {"a": "heldout", "b": "heldout", "t": "train"}
    cfg = EvaluateConfig(grasps_per_object=4)
    chosen = select_grasps(grasps, "optimization", split_of, cfg, seed=0)
    assert sorted(chosen.object_id.tolist()) == ["a"] * 4 + ["b"] * 3
    reasons = dict(zip(chosen.arrays["source_row"].tolist(), chosen.arrays["invalid_reason"].tolist()))
    assert reasons[10] == "non-positive or non-finite scale" and sum(r != "" for r in reasons.values()) == 1
    assert chosen.attrs["invalid_reasons"] == {"non-positive or non-finite scale": 1}
    assert set(chosen.arrays["split"]) == {"heldout"} and set(chosen.arrays["method"]) == {"optimization"}
    assert (chosen.arrays["sample_row"] == -1).all()
    again = select_grasps(grasps, "optimization", split_of, cfg, seed=0)
    assert np.array_equal(again.arrays["source_row"], chosen.arrays["source_row"])


def test_a_renamed_method_draws_with_its_frozen_label():
    """The optimization method draws the rows its old name "seed" drew, so a seed keeps choosing the same grasps."""
    from dexlite_pipeline.evaluation.selection import row_priorities

    grasps = _set(["a"] * 12 + ["b"] * 7)
    cfg = EvaluateConfig(grasps_per_object=3)
    chosen = select_grasps(grasps, "optimization", {"a": "heldout", "b": "heldout"}, cfg, seed=5)
    priority = row_priorities(5, "seed", len(grasps))
    expected = [sorted(rows[np.argsort(priority[rows], kind="stable")][:3].tolist()) for rows in (np.arange(12), np.arange(12, 19))]
    assert chosen.arrays["source_row"].tolist() == expected[0] + expected[1]
    assert chosen.arrays["source_row"].tolist() != select_grasps(grasps, "cvae_raw", {"a": "heldout", "b": "heldout"}, cfg, seed=5).arrays["source_row"].tolist()


def test_invalid_grasps_are_chosen_as_often_as_valid_ones():
    """A method emitting NaN poses for half its grasps gets about half its chosen grasps invalid, not none."""
    grasps = _set(["a"] * 400)
    grasps.arrays["hand_pose"][::2] = np.nan
    chosen = select_grasps(grasps, "cvae_raw", {"a": "heldout"}, EvaluateConfig(grasps_per_object=100), seed=3)
    invalid = (chosen.arrays["invalid_reason"] != "").sum()
    assert 35 <= invalid <= 65
    assert chosen.attrs["invalid_reasons"] == {"non-finite hand_pose": int(invalid)}


def _paired_stores(rng):
    """A sampled store (syntheses on held-out a and b, one with a NaN pose; expansions on train t), its
    post-optimized store (one row per sampled row) and its random-init baseline (one row per valid synthesis)."""
    ids = np.asarray(["a"] * 10 + ["b"] * 6 + ["t"] * 4, dtype=object)
    labels = np.asarray(["cvae_raw"] * 16 + ["cvae_expand_latent"] * 4, dtype=object)
    order = rng.permutation(len(ids))
    ids, labels = ids[order], labels[order]
    scales = np.resize(np.asarray([0.08, 0.1, 0.12], np.float32), len(ids))
    poses = rng.normal(size=(len(ids), 28)).astype(np.float32)
    poses[np.flatnonzero(ids == "a")[3]] = np.nan
    sample = GraspSet({"hand_pose": poses, "object_id": ids, "scale": scales, "method": labels})
    post = GraspSet({"hand_pose": poses + 0.01, "object_id": ids, "scale": scales, "method": labels, "raw_hand_pose": poses})
    targets = np.flatnonzero((labels == "cvae_raw") & np.isfinite(poses).all(axis=1))
    random_post = GraspSet({
        "hand_pose": rng.normal(size=(len(targets), 28)).astype(np.float32), "object_id": ids[targets], "scale": scales[targets],
        "method": np.full(len(targets), "random_post", dtype=object),
    })  # fmt: skip
    return {"sample": [sample], "post": [post], "random_post": [random_post]}


def _chosen_sample_rows(sources, method, cfg, seed=0):
    split_of = {"a": "heldout", "b": "heldout", "t": "train"}
    grasps = method_grasps(method, sources[METHOD_SOURCES[method]])
    rows = sample_rows_of(method, sources, {"a", "b", "t"})
    chosen = select_grasps(grasps, method, split_of, cfg, seed, rows)
    sample = sources["sample"][0]
    assert np.array_equal(sample.object_id[chosen.arrays["sample_row"]], chosen.object_id)
    assert np.array_equal(sample.scale[chosen.arrays["sample_row"]], chosen.scale)
    return chosen


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cvae_and_random_methods_are_evaluated_on_the_same_sampled_rows(seed):
    sources = _paired_stores(np.random.default_rng(seed))
    cfg = EvaluateConfig(grasps_per_object=4)
    raw, post, random_post = (_chosen_sample_rows(sources, m, cfg, seed) for m in ("cvae_raw", "cvae_post", "random_post"))
    assert sorted(raw.arrays["sample_row"]) == sorted(post.arrays["sample_row"])
    assert sorted(set(raw.object_id)) == ["a", "b"] and (raw.arrays["invalid_reason"] == post.arrays["invalid_reason"]).all()
    sample_poses = sources["sample"][0].hand_pose
    valid_raw = {int(r) for r in raw.arrays["sample_row"] if np.isfinite(sample_poses[r]).all()}
    # the baseline has no row for an invalid sample: it takes the next sampled row in the shared order instead
    assert valid_raw <= set(random_post.arrays["sample_row"].tolist())
    assert sorted(Counter(random_post.object_id.tolist()).items()) == [("a", 4), ("b", 4)]


def test_stores_that_do_not_line_up_with_the_sampled_rows_are_an_error():
    sources = _paired_stores(np.random.default_rng(0))
    sources["random_post"][0].arrays["scale"][0] += 0.01
    with pytest.raises(ValueError, match="do not line up"):
        sample_rows_of("random_post", sources, {"a", "b", "t"})
    sources["post"] = [sources["post"][0].select(np.arange(5))]
    with pytest.raises(ValueError, match="do not line up"):
        sample_rows_of("cvae_post", sources, {"a", "b", "t"})


def test_unpaired_methods_and_runs_without_sampled_stores_draw_over_their_own_rows():
    sources = _paired_stores(np.random.default_rng(0))
    assert sample_rows_of("optimization", sources, {"a", "b", "t"}) is None
    assert sample_rows_of("random_post", {"random_post": sources["random_post"]}, {"a", "b", "t"}) is None


def test_method_grasps_takes_only_pure_cvae_samples():
    sample = _set(["a", "a", "t"], {"method": np.asarray(["cvae_raw", "expansion", "cvae_raw"], dtype=object)})
    raw = method_grasps("cvae_raw", [sample])
    assert len(raw) == 2 and set(raw.arrays) == {"hand_pose", "object_id", "scale", "grasp_type"}
    assert raw.arrays["grasp_type"].tolist() == ["power", "power"]  # a store without types holds power grasps
    assert len(method_grasps("optimization", [sample])) == 3


def test_shipped_methods_read_the_shipped_models_rows_paired_raw_and_refined():
    """shipped_raw / shipped_post: the rows labelled shipped_raw of the sampled and post-optimized stores, drawn alike."""
    labels = np.asarray(["cvae_raw", "shipped_raw", "cvae_raw", "shipped_raw", "shipped_raw"], dtype=object)
    sample = _set(["a", "a", "b", "b", "b"], {"method": labels})
    post = _set(["a", "a", "b", "b", "b"], {"method": labels})
    assert METHOD_SOURCES["shipped_raw"] == "sample" and METHOD_SOURCES["shipped_post"] == "post"
    assert method_grasps("shipped_raw", [sample]).object_id.tolist() == ["a", "b", "b"]
    assert method_grasps("shipped_post", [post]).object_id.tolist() == ["a", "b", "b"]
    sources = {"sample": [sample], "post": [post]}
    np.testing.assert_array_equal(sample_rows_of("shipped_raw", sources, {"a", "b"}), [1, 3, 4])
    np.testing.assert_array_equal(sample_rows_of("shipped_post", sources, {"a", "b"}), [1, 3, 4])
    cfg = EvaluateConfig(methods=("shipped_raw", "shipped_post"), grasps_per_object=1)
    chosen = [select_grasps(method_grasps(m, sources[METHOD_SOURCES[m]]), m, {"a": "heldout", "b": "heldout"}, cfg, 0,
                            sample_rows_of(m, sources, {"a", "b"})) for m in cfg.methods]  # fmt: skip
    assert chosen[0].arrays["sample_row"].tolist() == chosen[1].arrays["sample_row"].tolist()  # the same samples, raw and refined


def test_optimization_method_keeps_every_attempt_and_costs_per_attempt():
    """No method is filtered before the evaluation: optimization's failing attempts are drawn too, and its cost is per attempt."""
    optimized = _set(["a", "a", "a", "a"], {"passes_energy_thresholds": np.array([True, False, False, True])})
    optimized.attrs.update({"seconds_per_grasp": 2.0, "seconds": 8.0, "passing": 2})
    assert len(method_grasps("optimization", [optimized])) == 4
    assert stage_seconds_per_grasp("optimization", {"optimized": [optimized]}) == {"optimized": 2.0}



def _evaluation_files(eval_dir):
    """The aggregate step's output options (and the report's inputs) in ``eval_dir``."""
    names = {"metrics": "metrics.csv", "per-object": "per_object.csv", "convergence": "convergence.csv", "budget": "budget.csv", "record": "evaluation.json"}
    return [arg for option, name in names.items() for arg in (f"--{option}", str(eval_dir / name))]

@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory, tiny_objects):
    rng = np.random.default_rng(0)
    root = tmp_path_factory.mktemp("eval_run")
    lift_config = {"friction": 0.6, "object_mass_kg": 0.1, "finger_kp": 5.0, "timestep_s": 0.002, "success_lift_ratio": 0.9}
    shard0 = simulated_shard(
        root / "sim_000.zarr",
        {"optimization": [True, False, False, False], "cvae_post": [True, True, False]},
        rng,
        {"lift_config": lift_config, "method_seconds_per_grasp": {"optimization": {"optimized": 3.0}, "cvae_post": {"sample": 0.01, "post": 0.5}},
         "methods_without_input": ["dexgraspnet"], "simulation_seconds_per_grasp": 0.2},
    )  # fmt: skip
    shard1 = simulated_shard(root / "sim_001.zarr", {"cvae_post": [True, None]}, rng, {"methods_without_input": ["dexgraspnet", "random_post"]})
    post = post_store(root / "post.zarr", 6, 21, rng, decay=0.2)  # E_fc < 0.3 from t = 7 (iteration 70)
    random_post = post_store(root / "random.zarr", 6, 21, rng, decay=0.045)  # from t = 27: never within 21
    eval_dir = root / "eval"
    eval_dir.mkdir()
    evaluate = {"methods": ["optimization", "cvae_post", "random_post", "dexgraspnet"], "rendered_per_method": 1}
    aggregate_cfg = json.dumps({"seed": 0, "evaluate": evaluate})
    run_config = {
        "seed": 7, "shards": 2, "objects": {"builtin_count": 40, "mesh_dirs": []}, "lift": lift_config, "evaluate": evaluate,
        "train": {"profile": "default", "max_steps": 2000}, "post_optimize": {"annealing": {"iterations": 200}, "keep_best": True},
    }  # fmt: skip
    objects = ["--objects", str(tiny_objects)]
    assert main(["evaluate", "--step", "aggregate", "--sim", str(shard0), "--sim", str(shard1), "--post", str(post), "--random-post", str(random_post),
                 *_evaluation_files(eval_dir), *objects, "--config-json", aggregate_cfg]) == 0  # fmt: skip
    history = root / "history.csv"
    pd.DataFrame({"step": np.arange(20), "loss": np.linspace(2, 1, 20), "kl": np.linspace(0, 1, 20)}).to_csv(history, index=False)
    report = root / "report.html"
    assert main(["report", *_evaluation_files(eval_dir), "--sim", str(shard0), "--sim", str(shard1), "--history", str(history), "--out", str(report),
                 *objects, "--config-json", json.dumps(run_config)]) == 0  # fmt: skip
    return eval_dir, report


def test_metrics_csv_from_tiny_run(tiny_run):
    eval_dir, _ = tiny_run
    table = pd.read_csv(eval_dir / "metrics.csv").set_index("method")
    assert list(table.index) == ["optimization", "cvae_post", "random_post"]  # dexgraspnet had no input anywhere
    assert table.loc["optimization", "lift_success_rate"] == 0.25
    # the invalid grasp of shard 1 is a failure: 3 of 5, not 3 of 4
    assert table.loc["cvae_post", "lift_success_rate"] == 0.6
    assert table.loc["cvae_post", ["n_grasps", "n_invalid"]].tolist() == [5, 1] and table.loc["optimization", "n_invalid"] == 0
    assert table.loc["cvae_post", "lift_success_boot_ci95_low"] <= 0.6 <= table.loc["cvae_post", "lift_success_boot_ci95_high"]
    assert table.loc["optimization", "object_success_rate"] == 1.0
    assert table.loc["cvae_post", "seconds_per_grasp"] == pytest.approx(0.51)
    assert table.loc["random_post", "n_grasps"] == 0 and np.isnan(table.loc["random_post", "lift_success_rate"])
    assert table.loc["cvae_post", "threshold_reached_fraction"] == 1.0
    assert table.loc["cvae_post", "threshold_iteration_median"] == 70
    assert table.loc["random_post", "threshold_reached_fraction"] == 0.0
    # random init ends at median E_post exp(-0.9) + 0.1; the CVAE start gets there at t = 5 (iteration 50)
    assert table.loc["random_post", "E_post_median_final"] == pytest.approx(np.exp(-0.9) + 0.1, rel=1e-5)  # CSV keeps 6 digits
    assert table.loc["cvae_post", "iterations_to_random_final_E_post"] == 50
    assert table.loc["random_post", "iterations_to_random_final_E_post"] == 200
    assert np.isnan(table.loc["optimization", "iterations_to_random_final_E_post"])
    per_object = pd.read_csv(eval_dir / "per_object.csv")
    assert per_object[["method", "object_id", "n_grasps", "n_invalid"]].values.tolist() == [["optimization", OBJECT_ID, 4, 0], ["cvae_post", OBJECT_ID, 5, 1]]
    curves = pd.read_csv(eval_dir / "convergence.csv")
    assert set(curves["method"]) == {"cvae_post", "random_post"} and (curves["q25"] <= curves["median"]).all()


def test_report_is_self_contained_with_pictures(tiny_run):
    _, report = tiny_run
    text = report.read_text()
    # opens from disk, nothing fetched: no script is loaded from elsewhere, and the page outside its inline
    # scripts names no web address (the inlined plotly.js holds addresses in code paths the 3-D view never
    # runs; the view's own browser test, tests/report/test_grasp_view.py, fails on any request)
    assert not re.search(r"<script[^>]*\bsrc\s*=", text, re.IGNORECASE)
    markup = re.sub(r"<script\b[^>]*>.*?</script>", "", text, flags=re.IGNORECASE | re.DOTALL)
    assert "http://" not in markup and "https://" not in markup
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', markup)
    # success bars, histograms, convergence, training curves, then a success and a failure per method
    assert len(images) == 4 + 2 * 2
    assert all(base64.b64decode(b)[:8] == b"\x89PNG\r\n\x1a\n" for b in images)
    for needle in ("Optimization from scratch", "CVAE samples + post-optimization", "friction", "object_mass_kg", "lift success ≈ 55%",
                   "n_invalid", "boot_ci95", "after 200 iterations at iteration 50: speed-up 4.0×", "object-level bootstrap"):
        assert needle in text, needle
    # the result sentence leads with the post-optimized samples: 3 of 5 lifted, none held against the pushes
    assert "<p class='result'>On 1 held-out object (5 grasps), 60.0% of CVAE samples + post-optimization held the object" in text
    # pictures: outcome in large type from both tests (the synthetic lifts all fail the pushes)
    assert text.count("<div class='outcome partial'>LIFTED, FAILS PUSHES</div>") == 2 and text.count("<div class='outcome dropped'>DROPPED</div>") == 2
    # the full tables are linked relative to the page (written one folder above them here)
    for name in ("metrics.csv", "per_object.csv", "convergence.csv"):
        assert f"<a href='eval/{name}'>{name}</a>" in text
    # the run's key settings, from the whole config the report was given, and the config itself
    for label, value in (("seed", "7"), ("built-in objects requested", "40"), ("lift: friction", "0.6"), ("training profile", "default"),
                         ("training steps (max_steps)", "2000"), ("training: steps run", "19 steps"), ("post-optimization iterations", "200"),
                         ("objects prepared (catalogs)", "1 heldout, 1 train; 0 rejected")):
        assert f"<tr><td>{label}</td><td>{value}</td></tr>" in text, label
    assert "<summary>whole config</summary>" in text and '&quot;max_steps&quot;: 2000' in text


def test_simulate_step_on_tiny_object(tmp_path, tiny_objects):
    """The per-shard step: selection, energies and the MuJoCo lift test, one store out; a NaN pose stays in as a failure."""
    from dexlite_pipeline.io.grasp_store import read_grasp_store, write_grasp_store
    from report_synthetic import grasp_poses

    rng = np.random.default_rng(1)
    optimized_store = tmp_path / "optimized.zarr"
    ids = [OBJECT_ID] * 3 + ["train_obj"] * 2
    poses = grasp_poses(5, rng)
    poses[1, 4] = np.nan
    write_grasp_store(optimized_store, GraspSet({"hand_pose": poses, "object_id": np.asarray(ids, dtype=object), "scale": np.full(5, 0.06, np.float32)}), {"seconds_per_grasp": 2.0})
    out = tmp_path / "sim.zarr"
    cfg = json.dumps({"seed": 0, "shards": 1, "device": "cpu", "evaluate": {"grasps_per_object": 3, "six_directions": False}, "scene": {"table": False}})
    assert main(["evaluate", "--step", "simulate", "--shard", "0", "--config-json", cfg, "--optimized", str(optimized_store), "--objects", str(tiny_objects), "--out", str(out)]) == 0
    result = read_grasp_store(out)
    assert len(result) == 3 and set(result.object_id) == {OBJECT_ID}
    for name in ("lift_success", "failure_reason", "E_fc", "penetration_mm", "contact_distance_mm", "filter_E_fc", "filter_E_dis"):
        assert name in result.arrays
    invalid = result.arrays["source_row"] == 1
    assert result.arrays["invalid_reason"][invalid].tolist() == ["non-finite hand_pose"] and not result.arrays["lift_success"][invalid].any()
    assert (result.arrays["invalid_reason"][~invalid] == "").all() and np.isfinite(result.arrays["E_fc"][~invalid]).all()
    assert result.attrs["invalid_reasons"]["optimization"] == {"non-finite hand_pose": 1}
    assert result.attrs["lift_config"]["six_directions"] is False
    assert result.attrs["method_seconds_per_grasp"] == {"optimization": {"optimized": 2.0}}
    without_input = {"cvae_raw", "cvae_post", "random_post", "dexgraspnet", "cvae_recon", "cvae_recon_post", "cvae_prior_train", "cvae_prior_train_post",
                     "shipped_raw", "shipped_post", "cvae_ranked", "cvae_ranked_post"}
    assert set(result.attrs["methods_without_input"]) == without_input


def test_simulate_step_on_a_table_rejects_hands_in_it_and_measures_reach_in_both_modes(tmp_path, tiny_objects):
    """Tabletop mode: a hand under the object is in its table (hand_in_table); in both modes every grasp gets its
    reach below the table in the resting pose, and metrics give the share of held grasps that stay above it."""
    from dexlite_pipeline.evaluation.protocol import TABLE_DEPTH
    from dexlite_pipeline.io.grasp_store import read_grasp_store, write_grasp_store
    from dexlite_pipeline.tabletop import reachable_on_table
    from report_synthetic import grasp_poses

    poses = grasp_poses(2, np.random.default_rng(1))
    poses[1, :3] = [0.0, 0.0, -0.3]  # 30 cm under the object: in its table
    optimized_store = tmp_path / "optimized.zarr"
    write_grasp_store(optimized_store, GraspSet({"hand_pose": poses, "object_id": np.asarray([OBJECT_ID] * 2, dtype=object), "scale": np.full(2, 0.06, np.float32)}),
                      {"seconds_per_grasp": 2.0})
    stability = tmp_path / "stability.parquet"
    pd.DataFrame({"object_id": [OBJECT_ID], "stable": [True], "support_nx": [0.0], "support_ny": [0.0], "support_nz": [1.0], "support_offset": [1.0]}).to_parquet(stability)
    results = {}
    for name, table in (("tabletop", True), ("floating", False)):
        cfg = json.dumps({"seed": 0, "shards": 1, "device": "cpu", "evaluate": {"grasps_per_object": 3, "six_directions": False}, "scene": {"table": table}})
        out = tmp_path / f"{name}.zarr"
        assert main(["evaluate", "--step", "simulate", "--shard", "0", "--config-json", cfg, "--optimized", str(optimized_store), "--objects", str(tiny_objects),
                     "--stability", str(stability), "--out", str(out)]) == 0
        results[name] = read_grasp_store(out)
    below = results["tabletop"].arrays["source_row"] == 1
    assert results["tabletop"].arrays["failure_reason"][below].tolist() == ["hand_in_table"]
    assert "hand_in_table" not in results["floating"].arrays["failure_reason"].tolist()
    for result in results.values():
        depth = result.arrays[TABLE_DEPTH]
        assert depth[result.arrays["source_row"] == 1][0] > 100.0 and np.isfinite(depth).all()
    share = reachable_on_table(np.array([True, True, False]), np.array([0.0, 5.0, 0.0]))
    assert share == {"held_reachable_on_table_rate": 0.5, "n_held_below_table": 1}


def test_split_without_objects_fails_in_one_line(tmp_path, capsys):
    objects = tmp_path / "objects"
    objects.mkdir()
    pd.DataFrame({"object_id": ["h1"], "split": ["heldout"], "status": ["ok"]}).to_parquet(objects / "catalog.parquet")
    cfg = json.dumps({"seed": 0, "shards": 1, "evaluate": {"splits": ["train"]}})
    code = main(["evaluate", "--step", "simulate", "--shard", "0", "--config-json", cfg, "--objects", str(objects), "--out", str(tmp_path / "sim.zarr")])
    error = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in error
    assert "config.evaluate.splits: no object of split train" in error and "their splits: heldout" in error
    assert not (tmp_path / "sim.zarr").exists()


def test_splits_are_the_catalog_split_names():
    from dexlite_pipeline.config import ConfigError, load_config, validate_config

    config = load_config(Path(__file__).resolve().parents[2] / "config.yaml")
    with pytest.raises(ConfigError, match="evaluate.splits.0: 'held_out' is not one of"):
        validate_config({**config, "evaluate": {**config["evaluate"], "splits": ["held_out"]}})
    validate_config({**config, "evaluate": {**config["evaluate"], "splits": ["train", "heldout"]}})
    with pytest.raises(ValueError, match="unknown split"):
        EvaluateConfig(splits=("held_out",))


def test_every_evaluate_setting_belongs_to_a_step_and_steps_read_only_theirs():
    from dataclasses import fields

    from dexlite_pipeline.evaluation.protocol import evaluate_config_from
    from dexlite_pipeline.evaluation.step_keys import AGGREGATE_KEYS, REPORT_KEYS, SIMULATE_KEYS

    assert {f.name for f in fields(EvaluateConfig)} == set(SIMULATE_KEYS) | set(AGGREGATE_KEYS) | set(REPORT_KEYS)
    cfg = evaluate_config_from({"evaluate": {"grasps_per_object": 5, "rendered_per_method": 7}}, SIMULATE_KEYS)
    assert cfg.grasps_per_object == 5 and cfg.rendered_per_method == EvaluateConfig().rendered_per_method


def test_coverage_arrays_touch_the_box_only_where_the_hand_is(tiny_objects):
    """Forward kinematics and the SDF: a hand on the box touches patches, one a metre away or invalid touches none."""
    from report_synthetic import grasp_poses

    from dexlite_pipeline.evaluation.config import DiversityConfig
    from dexlite_pipeline.evaluation.metrics import COVERAGE_PATCHES, TOUCHED_PATCHES
    from dexlite_pipeline.evaluation.protocol import coverage_arrays

    poses = grasp_poses(4, np.random.default_rng(0))
    poses[1, 2] = 1.0  # palm 1 m above the box
    poses[2] = np.nan
    grasps = GraspSet({
        "hand_pose": poses, "object_id": np.asarray([OBJECT_ID] * 3 + ["no_such_object"], dtype=object), "scale": np.full(4, 0.06, np.float32),
        "invalid_reason": np.asarray(["", "", "non-finite hand_pose", ""], dtype=object),
    })  # fmt: skip
    out = coverage_arrays(grasps, [tiny_objects], DiversityConfig(coverage_patches=16))
    assert out[COVERAGE_PATCHES].tolist() == [16, 16, 16, 0]  # the box has 128 surface samples; the unknown object none
    touched = out[TOUCHED_PATCHES]
    assert touched.shape == (4, 16) and touched[0].any() and not touched[1:].any()
    # a contact distance of a micrometre: the same grasp touches fewer patches or none
    tight = coverage_arrays(grasps, [tiny_objects], DiversityConfig(coverage_patches=16, coverage_contact_m=1e-6))[TOUCHED_PATCHES]
    assert tight[0].sum() < touched[0].sum()


def test_filter_contact_search_is_per_grasp_and_never_worse_than_the_nearest_four(tiny_objects):
    """The equal filter's contacts: the same for a grasp alone or in a batch; its score at most the nearest four's."""
    from report_synthetic import grasp_poses

    from dexlite_pipeline.energy.per_grasp import evaluate_grasp_energies
    from dexlite_pipeline.energy.config import EnergyWeights
    from dexlite_pipeline.evaluation.filter_energy import FILTER_CONTACTS, filter_energy_arrays

    poses = grasp_poses(6, np.random.default_rng(3))
    poses[4] = np.nan
    grasps = GraspSet({
        "hand_pose": poses, "object_id": np.asarray([OBJECT_ID] * 5 + ["no_such_object"], dtype=object), "scale": np.full(6, 0.06, np.float32),
        "invalid_reason": np.asarray([""] * 4 + ["non-finite hand_pose", ""], dtype=object),
    })  # fmt: skip
    weights = EnergyWeights()
    together = filter_energy_arrays(grasps, [tiny_objects], weights, batch_size=64)
    alone = filter_energy_arrays(grasps, [tiny_objects], weights, batch_size=1)
    for name, value in together.items():
        np.testing.assert_array_equal(value, alone[name], err_msg=name)
    assert np.isfinite(together["filter_E_fc"][:4]).all() and np.isnan(together["filter_E_fc"][4:]).all()
    assert (together[FILTER_CONTACTS][4:] == -1).all()
    nearest = evaluate_grasp_energies(grasps.select(np.arange(4)), [tiny_objects])
    searched = weights.fc * together["filter_E_fc"][:4] + weights.dis * together["filter_E_dis"][:4]
    assert (searched <= weights.fc * nearest["E_fc"] + weights.dis * nearest["E_dis"] + 1e-5).all()
