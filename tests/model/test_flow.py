"""The flow-matching generator (train.generator: flow): trains, samples, is deterministic, round-trips, runs the stages."""

import dataclasses
import json

import numpy as np
import pytest
import torch

from dexlite_pipeline.model.checkpoint import load_checkpoint, save_checkpoint
from dexlite_pipeline.model.config import TrainConfig
from dexlite_pipeline.model.data import ObjectClouds, build_training_data
from dexlite_pipeline.model.flow import GraspFlow, generator_family
from dexlite_pipeline.model.pose import POSE_FEATURE_DIM
from dexlite_pipeline.model.sampling import synthesize
from dexlite_pipeline.model.training import fit_training_codes, train_cvae


@pytest.fixture(scope="module")
def tiny_data(hand, tiny_assets, make_grasps):
    grasps = make_grasps(hand, 8, seed=1)
    return grasps, build_training_data(grasps, tiny_assets, hand)


def _config(small_model_config, **overrides):
    values = dict(epochs=100, max_steps=0, lr_warmup_steps=0, batch_size=8, clouds_per_batch=2, points_per_cloud=64, learning_rate=3e-3,
                  validation_fraction=0.0, generator="flow", flow_steps=4)
    values.update(overrides)
    return TrainConfig(model=small_model_config, **values)


def _sample(model, tiny_assets, seed=0):
    clouds = ObjectClouds(tiny_assets)
    return synthesize(model, clouds, np.array([0, 0, 1, 1, 1]), np.full(5, 0.1, np.float32), 64, torch.Generator().manual_seed(seed),
                      "neighbours", 1.0, True, "matched", 2, yaw_candidates=4)


def test_flow_trains_and_samples_poses(tiny_data, tiny_assets, small_model_config):
    grasps, data = tiny_data
    everything = np.arange(len(grasps))
    result = train_cvae(data, everything, np.zeros(0, np.int64), _config(small_model_config), None, seed=0)
    model = result.model
    assert isinstance(model, GraspFlow) and generator_family(model) == "flow"
    assert model.config.latent_dim == POSE_FEATURE_DIM and not hasattr(model, "encoder")
    assert result.history[-1]["train_recon"] < 0.75 * result.history[0]["train_recon"]  # the velocity error falls
    assert result.history[-1]["train_kl"] == 0.0
    fit = fit_training_codes(model, data, everything, _config(small_model_config))
    assert fit["grasps"] == len(grasps) and np.isfinite(fit["translation_error_mm_median"])
    # every stored code is N(0, I): the start is noise; the codes keep their conditions for the neighbour and anchor rules
    assert torch.count_nonzero(model.codes_mu) == 0 and torch.count_nonzero(model.codes_log_var) == 0
    assert model.codes_condition.shape == (len(grasps), small_model_config.condition_dim)
    poses = _sample(model, tiny_assets)
    assert poses.shape == (5, 28) and poses.dtype == torch.float32 and torch.isfinite(poses).all()


def test_flow_training_is_deterministic_for_a_seed(tiny_data, small_model_config):
    grasps, data = tiny_data
    config = _config(small_model_config, epochs=2, flow_solver="euler")
    runs = [train_cvae(data, np.arange(len(grasps)), np.zeros(0, np.int64), config, None, seed=3) for _ in range(2)]
    assert runs[0].history[-1]["train_total"] == runs[1].history[-1]["train_total"]
    for a, b in zip(runs[0].model.state_dict().values(), runs[1].model.state_dict().values()):
        assert torch.equal(a, b)
    other = train_cvae(data, np.arange(len(grasps)), np.zeros(0, np.int64), config, None, seed=4)
    assert other.history[-1]["train_total"] != runs[0].history[-1]["train_total"]


def test_flow_checkpoint_round_trips_and_records_the_family(tiny_data, tiny_assets, small_model_config, tmp_path):
    grasps, data = tiny_data
    config = _config(small_model_config, epochs=2, flow_steps=3, flow_solver="euler")
    everything = np.arange(len(grasps))
    model = train_cvae(data, everything, np.zeros(0, np.int64), config, None, seed=0).model
    fit_training_codes(model, data, everything, config)
    save_checkpoint(tmp_path / "flow.pt", model, config, {"seed": 0})
    assert torch.load(tmp_path / "flow.pt", weights_only=True)["generator"] == "flow"
    loaded, checkpoint = load_checkpoint(tmp_path / "flow.pt")
    assert isinstance(loaded, GraspFlow) and (loaded.steps, loaded.solver) == (3, "euler")
    assert checkpoint["generator"] == "flow" and checkpoint["flow"] == {"steps": 3, "solver": "euler"}
    assert torch.equal(_sample(model.eval(), tiny_assets, seed=2), _sample(loaded, tiny_assets, seed=2))
    # a CVAE records its family too, and a file from before families loads as a CVAE
    cvae_config = dataclasses.replace(config, generator="cvae")
    cvae = train_cvae(data, everything, np.zeros(0, np.int64), cvae_config, None, seed=0).model
    save_checkpoint(tmp_path / "cvae.pt", cvae, cvae_config, {})
    payload = torch.load(tmp_path / "cvae.pt", weights_only=True)
    assert payload["generator"] == "cvae"
    del payload["generator"]
    torch.save(payload, tmp_path / "old.pt")
    assert generator_family(load_checkpoint(tmp_path / "old.pt")[0]) == "cvae"
    with pytest.raises(ValueError, match="warm start"):  # a warm start keeps its family
        train_cvae(data, everything, np.zeros(0, np.int64), cvae_config, None, seed=0, initial_model=model)


def test_flow_through_the_train_and_sample_stages(tmp_path, hand, sphere_box_objects, make_grasps):
    import pandas as pd

    from dexlite_pipeline.cli import main
    from dexlite_pipeline.io.grasp_store import read_grasp_store, write_grasp_store

    catalog = tmp_path / "catalog"
    catalog.mkdir()
    pd.DataFrame({"object_id": ["box", "sphere"], "status": ["ok", "ok"], "split": ["train", "heldout"]}).to_parquet(catalog / "catalog.parquet")
    pd.DataFrame({"object_id": ["box", "sphere"], "stable": [True, True]}).to_parquet(tmp_path / "stability.parquet")
    grasps = make_grasps(hand, 16, seed=7)
    grasps.arrays["lift_success"] = np.ones(16, bool)
    write_grasp_store(tmp_path / "lift.zarr", grasps)
    config = json.dumps({
        "seed": 0, "device": "cpu", "shards": 1, "scene": {"table": False},
        "train": {"generator": "flow", "flow_steps": 3, "epochs": 2, "max_steps": 0, "batch_size": 8, "clouds_per_batch": 2,
                  "points_per_cloud": 64, "min_grasps": 4, "validation_fraction": 0.25,
                  "model": {"pointnet_widths": [16, 32, 64, 32], "encoder_hidden": [32], "decoder_hidden": [32], "latent_dim": 8,
                            "normalization": "none"}},
        "sample": {"synthesis_grasps_per_object": 4, "expansion_grasps_per_object": 2, "scales": [0.1], "shipped_model": "",
                   "ladder": False},
    })  # fmt: skip
    objects = ["--objects", str(catalog), "--objects", str(sphere_box_objects)]
    model = tmp_path / "model" / "cvae.pt"
    assert main(["train-cvae", "--config-json", config, "--lift", str(tmp_path / "lift.zarr"), *objects, "--model", str(model),
                 "--history", str(tmp_path / "model" / "history.csv"), "--curves", str(tmp_path / "model" / "curves.png")]) == 0
    assert torch.load(model, weights_only=True)["generator"] == "flow"
    assert main(["sample-grasps", "--config-json", config, "--model", str(model), "--stability", str(tmp_path / "stability.parquet"),
                 "--lift", str(tmp_path / "lift.zarr"), *objects, "--shard", "000", "--out", str(tmp_path / "sample.zarr")]) == 0
    sample = read_grasp_store(tmp_path / "sample.zarr")
    raw = sample.arrays["method"] == "cvae_raw"
    assert raw.sum() == 4 and set(sample.object_id[raw]) == {"sphere"}
    assert sample.hand_pose.shape[1] == 28 and np.isfinite(sample.hand_pose).all()
