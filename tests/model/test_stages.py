"""The three learning stages through the CLI on tiny inputs: train -> sample -> post-optimize."""

import json

import numpy as np
import pandas as pd
import pytest
import torch

from dexlite_pipeline.cli import main
from dexlite_pipeline.io.grasp_store import read_grasp_store, write_grasp_store


CONFIG = {
    "seed": 0,
    "device": "cpu",
    "shards": 1,
    "train": {
        "epochs": 3, "max_steps": 0, "batch_size": 8, "clouds_per_batch": 2, "points_per_cloud": 64, "min_grasps": 4,
        "validation_fraction": 0.25, "energy_point_spacing_m": 0.006,
        "model": {"pointnet_widths": [16, 32, 64, 32], "encoder_hidden": [32], "decoder_hidden": [32], "latent_dim": 8, "normalization": "batch"},
    },
    # no shipped model at first: the run's own rows alone; the shipped model's rows are checked on their own below
    "sample": {"synthesis_grasps_per_object": 5, "expansion_grasps_per_object": 6, "scales": [0.08, 0.1], "shipped_model": ""},
    "post_optimize": {"annealing": {"iterations": 10}, "energy_point_spacing_m": 0.006, "batch_size": 4},
    "energy": {"self_penetration_margin_m": 0.015},
    "scene": {"table": False},  # floating objects (tabletop mode: test_post_optimize_on_tables below)
}


def _model_outputs(folder):
    """The train-cvae output options for a model folder."""
    return ["--model", str(folder / "cvae.pt"), "--history", str(folder / "history.csv"), "--curves", str(folder / "training_curves.png")]


@pytest.fixture
def pipeline_inputs(tmp_path, hand, sphere_box_objects, make_grasps):
    """A catalog (box: train, sphere: held out), a stability table and one lift shard."""
    catalog_dir = tmp_path / "catalog"
    catalog_dir.mkdir()
    pd.DataFrame({"object_id": ["box", "sphere"], "status": ["ok", "ok"], "split": ["train", "heldout"]}).to_parquet(catalog_dir / "catalog.parquet")
    pd.DataFrame({"object_id": ["box", "sphere"], "stable": [True, True]}).to_parquet(tmp_path / "stability.parquet")
    grasps = make_grasps(hand, 16, seed=7)  # alternating box / sphere
    grasps.arrays["lift_success"] = np.arange(16) % 4 != 0
    write_grasp_store(tmp_path / "lift.zarr", grasps)
    return tmp_path, ["--objects", str(catalog_dir), "--objects", str(sphere_box_objects)]


def test_train_cvae_goes_on_from_the_state_an_interrupted_run_left(pipeline_inputs, monkeypatch):
    """A training killed before its model was written leaves its state (after epoch 2 of 3); the rerun goes on from it to
    the model an uninterrupted run makes and removes the state."""
    import dexlite_pipeline.model.trainer as trainer

    root, objects = pipeline_inputs

    def train(folder):
        return main(["train-cvae", "--config-json", json.dumps(CONFIG), "--lift", str(root / "lift.zarr"), *objects,
                     *_model_outputs(root / folder), "--state-every-s", "0"])

    assert train("whole") == 0
    assert not (root / "whole" / "cvae.pt.state").exists()

    def killed(*args, **kwargs):
        raise KeyboardInterrupt

    with monkeypatch.context() as patch:
        patch.setattr(trainer, "write_trained_model", killed)
        with pytest.raises(KeyboardInterrupt):
            train("resumed")
    assert (root / "resumed" / "cvae.pt.state").exists() and not (root / "resumed" / "cvae.pt").exists()
    assert train("resumed") == 0
    assert not (root / "resumed" / "cvae.pt.state").exists()
    whole, resumed = (torch.load(root / folder / "cvae.pt", weights_only=True) for folder in ("whole", "resumed"))
    assert (whole["resumed_after_epoch"], resumed["resumed_after_epoch"]) == (0, 2)
    assert whole["state_dict"].keys() == resumed["state_dict"].keys()
    assert all(torch.equal(whole["state_dict"][k], resumed["state_dict"][k]) for k in whole["state_dict"])


@pytest.mark.slow
def test_train_sample_post_optimize(pipeline_inputs):
    root, objects = pipeline_inputs
    cfg = json.dumps(CONFIG)
    assert main(["train-cvae", "--config-json", cfg, "--lift", str(root / "lift.zarr"), *objects, *_model_outputs(root / "model")]) == 0
    history = pd.read_csv(root / "model" / "history.csv")
    assert len(history) == 3 and {"train_recon", "val_recon", "train_pen", "val_kl"} <= set(history.columns)
    assert (root / "model" / "training_curves.png").stat().st_size > 0
    checkpoint = torch.load(root / "model" / "cvae.pt", weights_only=True)
    assert checkpoint["train_object_ids"] == ["box"]  # held-out sphere grasps never trained on
    assert checkpoint["excluded_grasps"] == {"failed the lift test": 4, "object not in the training split": 8}
    assert checkpoint["self_penetration_margin_m"] == 0.015  # E_spen as configured in section energy

    common = [*objects, "--shard", "000"]
    assert main(["sample-grasps", "--config-json", cfg, "--model", str(root / "model" / "cvae.pt"), "--stability", str(root / "stability.parquet"),
                 "--lift", str(root / "lift.zarr"), *common, "--out", str(root / "sample.zarr")]) == 0
    sample = read_grasp_store(root / "sample.zarr")
    method = sample.arrays["method"]
    assert sorted(set(sample.object_id[method == "cvae_raw"])) == ["sphere"] and (method == "cvae_raw").sum() == 5
    expansion = np.isin(method, ["cvae_expand_latent", "cvae_expand_point"])
    assert set(sample.object_id[expansion]) == {"box"} and expansion.sum() == 6
    # the learning ladder's rows on the training object: one reconstruction per grasp trained on, and pure syntheses
    reconstruction, prior = method == "cvae_recon", method == "cvae_prior_train"
    assert reconstruction.sum() == checkpoint["train_grasps"] == len(checkpoint["training_grasps"]["object_id"])
    assert set(sample.object_id[reconstruction]) == {"box"}
    assert set(sample.object_id[prior]) == {"box"} and prior.sum() == 5
    assert set(method) == {"cvae_raw", "cvae_expand_latent", "cvae_expand_point", "cvae_recon", "cvae_prior_train"}
    assert sample.attrs["seconds_per_grasp"] > 0 and np.isfinite(sample.hand_pose).all()
    # sample.ladder_grasps_per_object caps both ladder rungs per training object: a choice among the grasps trained on
    capped_cfg = json.dumps({**CONFIG, "sample": {**CONFIG["sample"], "ladder_grasps_per_object": 2}})
    assert main(["sample-grasps", "--config-json", capped_cfg, "--model", str(root / "model" / "cvae.pt"), "--stability", str(root / "stability.parquet"),
                 "--lift", str(root / "lift.zarr"), *common, "--out", str(root / "capped.zarr")]) == 0
    capped = read_grasp_store(root / "capped.zarr")
    capped_method = capped.arrays["method"]
    assert (capped_method == "cvae_recon").sum() == 2 and (capped_method == "cvae_prior_train").sum() == 2
    trained_on = {tuple(p) for p in np.asarray(checkpoint["training_grasps"]["hand_pose"], np.float32)}
    assert {tuple(p) for p in capped.arrays["reference_hand_pose"][capped_method == "cvae_recon"]} <= trained_on
    assert (capped_method == "cvae_raw").sum() == 5  # held-out synthesis is not capped

    # a shipped model adds its own syntheses (rows shipped_raw) on held-out objects it never trained on (here: the sphere),
    # after the run's own rows, which stay as they were
    shipped_cfg = json.dumps({**CONFIG, "sample": {**CONFIG["sample"], "shipped_model": str(root / "model" / "cvae.pt")}})
    assert main(["sample-grasps", "--config-json", shipped_cfg, "--model", str(root / "model" / "cvae.pt"), "--stability", str(root / "stability.parquet"),
                 "--lift", str(root / "lift.zarr"), *common, "--out", str(root / "shipped.zarr")]) == 0
    with_shipped = read_grasp_store(root / "shipped.zarr")
    shipped_mask = with_shipped.arrays["method"] == "shipped_raw"
    assert shipped_mask.sum() == 5 and set(with_shipped.object_id[shipped_mask]) == {"sphere"}
    np.testing.assert_array_equal(with_shipped.hand_pose[~shipped_mask], sample.hand_pose)
    assert with_shipped.attrs["shipped_skipped_objects"] == {}

    assert main(["post-optimize", "--config-json", cfg, "--sample", str(root / "sample.zarr"), *common,
                 "--out", str(root / "post.zarr"), "--random-out", str(root / "random.zarr")]) == 0
    post = read_grasp_store(root / "post.zarr")
    assert np.array_equal(post.arrays["raw_hand_pose"], sample.hand_pose)
    assert post.attrs["config"]["energy"] == {"self_penetration_margin_m": 0.015}
    assert post.arrays["trace_E_post"].shape == (len(sample), 11) and post.attrs["trace_iterations"] == list(range(11))
    # poses kept for the budget curve at the configured iterations within the 10 run (0 is the start)
    assert post.attrs["budget_iterations"] == [0] and post.arrays["budget_hand_pose"].shape == (len(sample), 1, 28)
    np.testing.assert_array_equal(post.arrays["budget_hand_pose"][:, 0], sample.hand_pose)
    assert {"E_fc", "raw_E_fc", "E_post", "raw_E_post", "penetration_mm", "raw_penetration_mm"} <= set(post.arrays)
    assert np.array_equal(post.arrays["method"], method)
    baseline = read_grasp_store(root / "random.zarr")
    assert len(baseline) == 5 and set(baseline.arrays["method"]) == {"random_post"}
    assert sorted(baseline.object_id) == sorted(sample.object_id[method == "cvae_raw"])
    assert baseline.arrays["trace_E_post"].shape == (5, 11)
    # Random starts are 0.2-0.3 m away: their palms start far from the object.
    assert np.linalg.norm(baseline.arrays["raw_hand_pose"][:, :3], axis=1).min() > 0.15


@pytest.mark.slow
def test_the_shipped_model_skips_held_out_objects_it_trained_on(pipeline_inputs, tiny_assets):
    """An object in the shipped model's training set is not a test of generalization: left out, with the reason."""
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.sample_shard import shipped_rows
    from dexlite_pipeline.model.config import SampleConfig

    root, objects = pipeline_inputs
    assert main(["train-cvae", "--config-json", json.dumps(CONFIG), "--lift", str(root / "lift.zarr"), *objects, *_model_outputs(root / "model")]) == 0
    clouds = ObjectClouds(tiny_assets)
    rows, left_out = shipped_rows(str(root / "model" / "cvae.pt"), ["box", "sphere"], clouds, SampleConfig(synthesis_grasps_per_object=3),
                                  torch.Generator().manual_seed(0), "cpu")  # fmt: skip
    assert left_out == {"box": "the shipped model was trained on it"}
    assert rows.object_id == ["sphere"] * 3 and rows.method == ["shipped_raw"] * 3


def test_training_refuses_too_few_grasps(pipeline_inputs, capsys):
    root, objects = pipeline_inputs
    cfg = json.dumps({**CONFIG, "train": {**CONFIG["train"], "min_grasps": 100}})
    assert main(["train-cvae", "--config-json", cfg, "--lift", str(root / "lift.zarr"), *objects, *_model_outputs(root / "model")]) == 2
    assert "train.min_grasps is 100" in capsys.readouterr().err
    assert not (root / "model" / "cvae.pt").exists()


def test_lift_shards_keep_optimized_contacts_and_drop_imported_ones(tmp_path, hand, make_grasps):
    from dexlite_pipeline.model.trainer import read_lift_shards

    grasps = make_grasps(hand, 4, seed=3)
    grasps.arrays["lift_success"] = np.ones(4, bool)
    grasps.arrays["origin"] = np.array(["optimization", "dexgraspnet", "optimization", "dexgraspnet"], dtype=object)
    grasps.arrays["contact_index"] = np.arange(16, dtype=np.int64).reshape(4, 4)  # curation's scoring contacts for imported rows
    write_grasp_store(tmp_path / "with_origin.zarr", grasps)
    no_contacts = make_grasps(hand, 2, seed=4)
    no_contacts.arrays["lift_success"] = np.ones(2, bool)
    write_grasp_store(tmp_path / "no_contacts.zarr", no_contacts)
    contacts = read_lift_shards([str(tmp_path / "with_origin.zarr"), str(tmp_path / "no_contacts.zarr")]).arrays["contact_index"]
    np.testing.assert_array_equal(contacts[[0, 2]], [[0, 1, 2, 3], [8, 9, 10, 11]])
    assert (contacts[[1, 3, 4, 5]] == -1).all()


def test_post_optimize_on_tables_raises_starts_and_keeps_random_palms_above(tmp_path, hand, sphere_box_objects, make_grasps):
    """Tabletop mode: sampled starts with a hand in the table are raised above it before refinement (the shift
    recorded, the sampled pose kept as raw_hand_pose), E_post includes E_table, random palms start above the
    table, every row records its plane; an object without a resting pose is a reason, not a crash."""
    from dexlite_pipeline.model.methods import SYNTHESIS

    grasps = make_grasps(hand, 6, seed=3)  # alternating box / sphere
    grasps.arrays["hand_pose"][0, 2] = -0.2  # a box grasp's palm 20 cm under the box: deep in the table
    grasps.arrays["method"] = np.full(len(grasps), SYNTHESIS, dtype=object)
    write_grasp_store(tmp_path / "sample.zarr", grasps)
    # The box (extents 1.2 x 0.9 x 0.7) lies flat; the sphere has no resting pose here.
    pd.DataFrame({"object_id": ["box", "sphere"], "stable": [True, True], "support_nx": [0.0, np.nan], "support_ny": [0.0, np.nan],
                  "support_nz": [1.0, np.nan], "support_offset": [0.35, np.nan]}).to_parquet(tmp_path / "stability.parquet")
    cfg = json.dumps({**CONFIG, "scene": {"table": True}})
    args = ["post-optimize", "--config-json", cfg, "--sample", str(tmp_path / "sample.zarr"), "--objects", str(sphere_box_objects), "--shard", "000",
            "--stability", str(tmp_path / "stability.parquet"), "--out", str(tmp_path / "post.zarr"), "--random-out", str(tmp_path / "random.zarr")]
    assert main(args) == 0
    post, baseline = read_grasp_store(tmp_path / "post.zarr"), read_grasp_store(tmp_path / "random.zarr")
    box = post.object_id == "box"
    assert set(post.arrays["failure_reason"][~box]) == {"no resting pose (tabletop mode)"}
    assert post.arrays["start_table_shift_m"][0] > 0.1 and np.array_equal(post.arrays["raw_hand_pose"], grasps.hand_pose)
    assert post.arrays["budget_hand_pose"][0, 0, 2] > grasps.hand_pose[0, 2] + 0.1  # the run started from the raised pose
    assert np.isfinite(post.arrays["E_table"][box]).all() and post.attrs["scene"] == {"table": True}
    np.testing.assert_allclose(post.arrays["support_offset_m"][box], 0.35 * post.scale[box], rtol=1e-6)
    assert set(baseline.object_id) == {"box"}
    start_heights = baseline.arrays["raw_hand_pose"][:, 2] + baseline.arrays["support_offset_m"]
    assert (start_heights >= 0).all()


def test_training_on_tables_weighs_e_table(pipeline_inputs):
    """Tabletop mode with train.energy_weights.table > 0: E_table is a loss term (history column train_table, finite);
    floating training has no such term."""
    root, objects = pipeline_inputs
    rest = {"support_nx": [0.0, 0.0], "support_ny": [0.0, 0.0], "support_nz": [1.0, 1.0], "support_offset": [0.35, 1 / 1.03]}
    pd.DataFrame({"object_id": ["box", "sphere"], "stable": [True, True], **rest}).to_parquet(root / "tables.parquet")
    train = {**CONFIG["train"], "epochs": 1, "energy_weights": {"table": 1.0}}
    tabletop = json.dumps({**CONFIG, "train": train, "scene": {"table": True}})
    args = ["train-cvae", "--lift", str(root / "lift.zarr"), *objects]
    assert main([*args, "--config-json", tabletop, "--stability", str(root / "tables.parquet"), *_model_outputs(root / "tabletop")]) == 0
    history = pd.read_csv(root / "tabletop" / "history.csv")
    assert np.isfinite(history["train_table"]).all() and (history["train_table"] >= 0).all()
    floating = json.dumps({**CONFIG, "train": train})
    assert main([*args, "--config-json", floating, *_model_outputs(root / "floating")]) == 0
    assert "train_table" not in pd.read_csv(root / "floating" / "history.csv").columns


@pytest.mark.slow
def test_train_seed_sets_the_training_alone(pipeline_inputs):
    """train.seed trains as the run's seed would, on the same data: training seeds without re-making the data."""
    root, objects = pipeline_inputs

    def train(folder, config):
        assert main(["train-cvae", "--config-json", json.dumps(config), "--lift", str(root / "lift.zarr"), *objects, *_model_outputs(root / folder)]) == 0
        return torch.load(root / folder / "cvae.pt", weights_only=True)

    by_run_seed = train("run_seed_3", {**CONFIG, "seed": 3})
    by_train_seed = train("train_seed_3", {**CONFIG, "train": {**CONFIG["train"], "seed": 3}})
    default = train("default", CONFIG)
    assert by_train_seed["seed"] == by_run_seed["seed"] == 3 and default["seed"] == 0
    state_3, state_train_3, state_0 = by_run_seed["state_dict"], by_train_seed["state_dict"], default["state_dict"]
    assert all(torch.equal(state_3[name], state_train_3[name]) for name in state_3)
    assert not all(torch.equal(state_3[name], state_0[name]) for name in state_3)


@pytest.mark.slow
def test_training_without_energy_weights_builds_no_energy_and_trains_the_same(pipeline_inputs, monkeypatch):
    """Every train.energy_weights 0 (the default): the loss scores no decoded pose, so training builds no GraspEnergy
    (its SDF bank and point sets grow with the objects: memory) and trains the same model as with one built."""
    from dexlite_pipeline.energy.grasp_energy import GraspEnergy
    from dexlite_pipeline.model import trainer

    root, objects = pipeline_inputs

    def train(folder):
        assert main(["train-cvae", "--config-json", json.dumps(CONFIG), "--lift", str(root / "lift.zarr"), *objects, *_model_outputs(root / folder)]) == 0
        return torch.load(root / folder / "cvae.pt", weights_only=True)["state_dict"]

    built = []
    original = GraspEnergy.from_assets.__func__
    monkeypatch.setattr(GraspEnergy, "from_assets", classmethod(lambda cls, *a, **k: built.append(1) or original(cls, *a, **k)))
    without = train("without")
    assert built == []
    monkeypatch.setattr(trainer, "uses_energies", lambda *a, **k: True)
    with_energy = train("with")
    assert built == [1]
    assert all(torch.equal(without[name], with_energy[name]) for name in without)


@pytest.mark.slow
def test_post_optimization_in_object_groups(pipeline_inputs, hand, make_grasps, monkeypatch):
    """post_optimize.objects_per_energy: a shard of more objects is refined one group of objects at a time (one energy
    held at once); every row is still refined in its place, and a shard of no more objects than a group is refined
    exactly as all at once (0)."""
    from dexlite_pipeline.energy.grasp_energy import GraspEnergy

    root, objects = pipeline_inputs
    sampled = make_grasps(hand, 12, seed=3)  # alternating box / sphere
    sampled.arrays["method"] = np.array(["cvae_raw", "cvae_expand_latent"] * 6, dtype=object)
    write_grasp_store(root / "sampled.zarr", sampled)
    built = []
    original = GraspEnergy.from_assets.__func__
    monkeypatch.setattr(GraspEnergy, "from_assets", classmethod(lambda cls, hand_model, assets, *a, **k: built.append(len(assets)) or original(cls, hand_model, assets, *a, **k)))

    def post(name, objects_per_energy):
        config = {**CONFIG, "post_optimize": {**CONFIG["post_optimize"], "objects_per_energy": objects_per_energy}}
        assert main(["post-optimize", "--config-json", json.dumps(config), "--sample", str(root / "sampled.zarr"), *objects, "--shard", "000",
                     "--out", str(root / f"{name}.zarr"), "--random-out", str(root / f"{name}_random.zarr")]) == 0
        return read_grasp_store(root / f"{name}.zarr"), read_grasp_store(root / f"{name}_random.zarr")

    together, together_random = post("together", 0)
    one_group, one_group_random = post("one_group", 2)
    assert built == [2, 2]
    for name in together.arrays:
        np.testing.assert_array_equal(together.arrays[name], one_group.arrays[name], err_msg=name)
    np.testing.assert_array_equal(together_random.hand_pose, one_group_random.hand_pose)

    built.clear()
    grouped, grouped_random = post("grouped", 1)
    assert built == [1, 1]
    np.testing.assert_array_equal(grouped.arrays["raw_hand_pose"], sampled.hand_pose)
    assert list(grouped.object_id) == list(sampled.object_id) and list(grouped.arrays["method"]) == list(sampled.arrays["method"])
    assert np.isfinite(grouped.hand_pose).all() and (grouped.arrays["failure_reason"] == "").all()
    assert sorted(grouped_random.object_id) == sorted(sampled.object_id[sampled.arrays["method"] == "cvae_raw"])
    assert np.isfinite(grouped_random.hand_pose).all()
