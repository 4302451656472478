"""Training: the loss falls on a handful of grasps, runs are deterministic, checkpoints round-trip."""

import dataclasses

import numpy as np
import pytest
import torch

from dexlite_pipeline.energy.config import EnergyConfig, EnergyWeights
from dexlite_pipeline.energy.grasp_energy import GraspEnergy
from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix
from dexlite_pipeline.model.checkpoint import CheckpointError, kept_code_rows, load_checkpoint, save_capped_copy, save_checkpoint, save_half_precision_copy
from dexlite_pipeline.model.data import build_training_data, select_training_grasps, split_validation
from dexlite_pipeline.model.network import anchor_at
from dexlite_pipeline.model.pose import features_to_pose
from dexlite_pipeline.model.config import TrainConfig
from dexlite_pipeline.model.training import fit_training_codes, grasp_energy_terms, train_cvae


@pytest.fixture(scope="module")
def setup(hand, tiny_assets, request):
    make_grasps = request.getfixturevalue("make_grasps")
    grasps = make_grasps(hand, 8, seed=1)
    data = build_training_data(grasps, tiny_assets, hand)
    energy = GraspEnergy.from_assets(hand, tiny_assets, EnergyConfig(object_point_spacing_m=0.005))
    return grasps, data, grasp_energy_terms(energy)


WRITEUP_ENERGY_WEIGHTS = dict(energy_weights=EnergyWeights(fc=1.0, dis=100.0, pen=100.0, spen=10.0, joints=1.0))  # the write-up's


def _config(small_model_config, **overrides):
    values = dict(epochs=30, max_steps=0, batch_size=8, clouds_per_batch=2, points_per_cloud=64, learning_rate=3e-3, validation_fraction=0.0)
    values.update(overrides)
    return TrainConfig(model=small_model_config, **values)


def test_loss_falls_when_overfitting_a_handful_of_grasps(setup, small_model_config):
    grasps, data, energy_terms = setup
    everything = np.arange(len(grasps))
    memorize = _config(small_model_config, rotation_augmentation=False, **WRITEUP_ENERGY_WEIGHTS)
    result = train_cvae(data, everything, np.zeros(0, np.int64), memorize, energy_terms, seed=0)
    first, last = result.history[0], result.history[-1]
    assert last["train_total"] < 0.5 * first["train_total"]
    assert all(np.isfinite(last[f"train_{k}"]) for k in ("fc", "dis", "pen", "spen", "joints", "kl"))
    # Reconstruction alone (energy weights 0): the decoder learns to reproduce these grasps.
    no_energy = _config(small_model_config, epochs=100, rotation_augmentation=False, energy_weights=EnergyWeights(0.0, 0.0, 0.0, 0.0, 0.0))
    result = train_cvae(data, everything, np.zeros(0, np.int64), no_energy, energy_terms, seed=0)
    assert result.history[-1]["train_recon"] < 0.3 * result.history[0]["train_recon"]
    # energies that are not weighted are not computed (they log as NaN)
    assert all(np.isnan(result.history[-1][f"train_{k}"]) for k in ("fc", "dis", "pen", "spen", "joints"))


def test_training_is_deterministic_for_a_seed(setup, small_model_config):
    grasps, data, energy_terms = setup
    config = _config(small_model_config, epochs=2, validation_fraction=0.25)
    train, val = split_validation(len(grasps), 0.25, seed=0)
    runs = [train_cvae(data, train, val, config, energy_terms, seed=5) for _ in range(2)]
    assert runs[0].history[-1]["val_total"] == runs[1].history[-1]["val_total"]
    for a, b in zip(runs[0].model.state_dict().values(), runs[1].model.state_dict().values()):
        assert torch.equal(a, b)
    other = train_cvae(data, train, val, config, energy_terms, seed=6)
    assert other.history[-1]["train_total"] != runs[0].history[-1]["train_total"]


def test_a_warm_start_goes_on_from_the_given_model(setup, small_model_config):
    grasps, data, energy_terms = setup
    everything, none = np.arange(len(grasps)), np.zeros(0, np.int64)
    config = _config(small_model_config, epochs=40, rotation_augmentation=False)
    first = train_cvae(data, everything, none, config, energy_terms, seed=0)
    start_loss = first.history[-1]["train_recon"]
    short = _config(small_model_config, epochs=1, rotation_augmentation=False)
    warm = train_cvae(data, everything, none, short, energy_terms, seed=1, initial_model=first.model)
    cold = train_cvae(data, everything, none, short, energy_terms, seed=1)
    assert warm.model is first.model  # trained on in place
    assert warm.history[0]["train_recon"] < 0.5 * cold.history[0]["train_recon"]
    assert warm.history[0]["train_recon"] < 3 * start_loss
    other = _config(dataclasses.replace(small_model_config, latent_dim=small_model_config.latent_dim + 1), epochs=1)
    with pytest.raises(ValueError, match="warm start"):
        train_cvae(data, everything, none, other, energy_terms, seed=1, initial_model=first.model)


def test_step_budget_ends_training_mid_epoch(setup, small_model_config):
    grasps, data, energy_terms = setup
    # 8 grasps in batches of 2 are 4 steps an epoch: a budget of 7 ends inside the second epoch.
    config = _config(small_model_config, epochs=30, max_steps=7, batch_size=2)
    result = train_cvae(data, np.arange(len(grasps)), np.zeros(0, np.int64), config, energy_terms, seed=0)
    assert result.steps == 7
    assert [row["step"] for row in result.history] == [4, 7]


def test_checkpoint_round_trip_loads_weights_only(tmp_path, setup, small_model_config, random_clouds):
    grasps, data, energy_terms = setup
    config = _config(small_model_config, epochs=1)
    model = train_cvae(data, np.arange(len(grasps)), np.zeros(0, np.int64), config, energy_terms, seed=0).model
    fit_training_codes(model, data, np.arange(len(grasps)), config)  # the codes the sampling priors read, stored with the model
    path = save_checkpoint(tmp_path / "cvae.pt", model, config, {"seed": 0, "train_object_ids": ["box", "sphere"]})
    raw = torch.load(path, weights_only=True)
    assert raw["train_config"]["points_per_cloud"] == 64 and raw["model_config"]["latent_dim"] == 8
    loaded, meta = load_checkpoint(path)
    assert meta["train_object_ids"] == ["box", "sphere"]
    model.eval()
    clouds = random_clouds(2, 64)
    latent = torch.randn(3, 8)
    with torch.no_grad():
        cloud_index, point_index = torch.tensor([0, 1, 1]), torch.tensor([1, 2, 3])
        anchor = anchor_at(clouds, cloud_index, point_index)
        expected = features_to_pose(model.decode(latent, model.condition(clouds, cloud_index, point_index), anchor))
        got = features_to_pose(loaded.decode(latent, loaded.condition(clouds, cloud_index, point_index), anchor))
    assert torch.equal(expected, got)
    # the half-precision copy (how the shipped model is stored): about half the bytes, float32 when loaded, outputs close
    half = save_half_precision_copy(path, tmp_path / "half.pt")
    assert half.stat().st_size < 0.6 * path.stat().st_size and torch.load(half, weights_only=True)["stored_dtype"] == "float16"
    loaded_half, _ = load_checkpoint(half)
    assert all(p.dtype == torch.float32 for p in loaded_half.parameters())
    with torch.no_grad():
        got_half = features_to_pose(loaded_half.decode(latent, loaded_half.condition(clouds, cloud_index, point_index), anchor))
    assert torch.allclose(expected, got_half, atol=0.02) and not torch.equal(expected, got_half)
    # capped codes: the kept rows of every code array agree, and the copy records how many it kept
    capped = save_half_precision_copy(path, tmp_path / "capped.pt", max_codes_per_cloud=1)
    raw_capped = torch.load(capped, weights_only=True)
    clouds_before = raw["state_dict"]["codes_cloud"]
    kept = kept_code_rows(clouds_before, raw["state_dict"]["codes_type"], 1)
    assert raw_capped["codes_kept"] == {"max_codes_per_cloud": 1, "seed": 0, "before": len(clouds_before), "after": len(kept)}
    assert len(kept) == len(torch.unique(clouds_before)) < len(clouds_before)
    for key in ("codes_mu", "codes_log_var", "codes_cloud", "codes_type"):
        assert torch.equal(raw_capped["state_dict"][key], raw["state_dict"][key][kept].to(raw_capped["state_dict"][key].dtype))
    # each cloud's global feature is stored once, its codes' own columns each: loading puts back every code's condition
    width = small_model_config.pointnet_widths[-1]
    assert "codes_condition" not in raw_capped["state_dict"]
    assert len(raw_capped["state_dict"]["cloud_global_condition"]) == len(torch.unique(raw_capped["state_dict"]["codes_cloud"]))
    loaded_capped, _ = load_checkpoint(capped)
    assert len(loaded_capped.codes_mu) == len(kept)
    assert torch.equal(loaded_capped.codes_condition, raw["state_dict"]["codes_condition"][kept].half().float())
    assert loaded_capped.codes_condition.shape[1] > width
    # the float32 copy with the same cap (measured in a run) keeps the same rows; halving it after keeps its record
    float32_capped = save_capped_copy(path, tmp_path / "capped32.pt", max_codes_per_cloud=1)
    raw32 = torch.load(float32_capped, weights_only=True)
    assert torch.equal(raw32["state_dict"]["codes_cloud"], raw_capped["state_dict"]["codes_cloud"]) and "stored_dtype" not in raw32
    again = torch.load(save_half_precision_copy(float32_capped, tmp_path / "again.pt", max_codes_per_cloud=1), weights_only=True)
    assert again["codes_kept"] == raw_capped["codes_kept"] and torch.equal(again["state_dict"]["codes_mu"], raw_capped["state_dict"]["codes_mu"])
    (tmp_path / "bad.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match="bad.pt"):
        load_checkpoint(tmp_path / "bad.pt")


def test_selection_keeps_lift_successes_of_training_objects_only(hand, make_grasps):
    grasps = make_grasps(hand, 6, seed=2)
    grasps.arrays["lift_success"] = np.array([True, True, False, True, True, True])
    grasps.arrays["hand_pose"][4, 0] = np.nan
    grasps.arrays["object_id"][5] = "heldout_thing"
    kept, excluded = select_training_grasps(grasps, {"box", "sphere"}, {"box", "sphere", "heldout_thing"})
    assert len(kept) == 3
    assert excluded == {"failed the lift test": 1, "non-finite hand_pose": 1, "object not in the training split": 1}


def test_no_lifted_grasps_is_zero_training_grasps_not_a_format_error():
    """Empty lift shards (nothing curated) hold no arrays: that is too little data, which the min_grasps check names."""
    from dexlite_pipeline.io.grasp_store import GraspSet

    kept, excluded = select_training_grasps(GraspSet.concatenate([]), {"box"}, {"box"})
    assert len(kept) == 0 and excluded == {}


def test_loss_energies_use_the_contacts_a_grasp_was_made_with(hand, tiny_assets, make_grasps):
    energy = GraspEnergy.from_assets(hand, tiny_assets, EnergyConfig(object_point_spacing_m=0.005))
    terms = grasp_energy_terms(energy, contact_samples=8)
    grasps = make_grasps(hand, 4, seed=3)
    pose = torch.as_tensor(grasps.hand_pose)
    parts = dict(palm_rot=euler_xyz_to_matrix(pose[:, 3:6]), palm_t=pose[:, :3], joints=pose[:, 6:])
    object_index, scale = energy.object_index(grasps.object_id), torch.as_tensor(grasps.scale)
    stored = torch.tensor([[0, 1, 2, 3], [10, 30, 50, 70], [-1, -1, -1, -1], [5, 45, 85, 125]])
    got = terms(*parts.values(), object_index, scale, stored)
    known = torch.tensor([0, 1, 3])
    direct = energy(**{k: v[known] for k, v in parts.items()}, object_index=object_index[known], scale=scale[known], contact_index=stored[known])
    assert torch.allclose(got["fc"][known], direct.terms["E_fc"]) and torch.allclose(got["dis"][known], direct.terms["E_dis"])
    # The grasp without stored contacts gets searched ones, never worse than the nearest four pads.
    one = torch.tensor([2])
    nearest = energy(**{k: v[one] for k, v in parts.items()}, object_index=object_index[one], scale=scale[one])
    weights = energy.weights
    searched = weights.fc * got["fc"][2] + weights.dis * got["dis"][2]
    assert searched <= weights.fc * nearest.terms["E_fc"][0] + weights.dis * nearest.terms["E_dis"][0] + 1e-6


def test_kept_code_rows_cap_each_cloud_and_let_its_grasp_types_take_turns():
    """At most the cap per cloud; a cloud's rare type keeps its code; the same rows for a seed; every row with cap 0."""
    cloud = torch.tensor([0, 0, 0, 0, 0, 1, 1, 2])
    grasp_type = torch.tensor([0, 0, 0, 0, 1, 0, 0, 2])
    for seed in range(5):
        kept = kept_code_rows(cloud, grasp_type, 2, seed)
        assert torch.equal(kept, kept_code_rows(cloud, grasp_type, 2, seed)) and torch.equal(kept, torch.sort(kept).values)
        assert torch.bincount(cloud[kept]).tolist() == [2, 2, 1]
        assert 4 in kept.tolist()  # cloud 0's one type-1 code
    assert kept_code_rows(cloud, grasp_type, 0).tolist() == list(range(8))
    chosen = {tuple(kept_code_rows(cloud, grasp_type, 2, seed).tolist()) for seed in range(10)}
    assert len(chosen) > 1  # the choice among cloud 0's type-0 codes follows the seed
