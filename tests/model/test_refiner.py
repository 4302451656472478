"""The refiner: its reading of the surface (heights and distances of the hand's points), an untrained refiner returning
the decoded pose, a training that lowers the refined pose's error below the decoder's, files that keep it, and sampling
that uses it."""

import dataclasses

import numpy as np
import pytest
import torch

from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix
from dexlite_pipeline.model.config import REFINE_TERM, ModelConfig, TrainConfig
from dexlite_pipeline.model.data import build_training_data
from dexlite_pipeline.model.network import GraspCVAE
from dexlite_pipeline.model.pose import pose_to_features
from dexlite_pipeline.model.refiner import READING_CLIP_M, READING_UNIT_M, hand_points, reading_points, surface_reading
from dexlite_pipeline.model.trainer import unbuilt_energy_terms
from dexlite_pipeline.model.training import train_cvae


@pytest.fixture
def refiner_config(small_model_config):
    return dataclasses.replace(small_model_config, refiner_hidden=(64, 64))


def _plane_cloud(points: int = 400, height: float = 0.0) -> torch.Tensor:
    """(1, points, 6) a 40 cm square of the plane z = ``height`` with normals +z."""
    generator = torch.Generator().manual_seed(0)
    xy = (torch.rand(points, 2, generator=generator) - 0.5) * 0.4
    return torch.cat([xy, torch.full((points, 1), height), torch.zeros(points, 2), torch.ones(points, 1)], dim=1)[None]


def test_the_reading_is_each_points_height_over_the_surface_and_its_distance(hand):
    pose = torch.zeros(1, 6 + 22)
    pose[0, 2] = 0.3  # far above the plane: every reading at the clip
    features = pose_to_features(pose)
    far = surface_reading(hand, features, _plane_cloud(), torch.zeros(1, dtype=torch.long))
    assert far.shape == (1, 2 * reading_points(hand))
    assert torch.allclose(far, torch.full_like(far, READING_CLIP_M / READING_UNIT_M))
    points = hand_points(hand, features)[0]
    lowest = float(points[:, 2].min())
    cloud = _plane_cloud(20_000, height=lowest + 0.005)  # the plane 5 mm above the hand's lowest point: that point is 5 mm under it
    reading = surface_reading(hand, features, cloud, torch.zeros(1, dtype=torch.long))[0]
    count = reading_points(hand)
    heights, distances = reading[:count] * READING_UNIT_M, reading[count:] * READING_UNIT_M
    expected = (points[:, 2] - (lowest + 0.005)).clamp(-READING_CLIP_M, READING_CLIP_M)
    assert torch.allclose(heights, expected, atol=1e-6)
    assert float(heights.min()) == pytest.approx(-0.005, abs=1e-6)
    assert (distances >= heights.abs() - 1e-6).all() and (distances <= READING_CLIP_M + 1e-7).all()


def test_an_untrained_refiner_returns_the_decoded_pose_and_a_model_without_one_has_none(hand, refiner_config, small_model_config, random_clouds):
    torch.manual_seed(0)
    model = GraspCVAE(refiner_config).eval()
    assert GraspCVAE(small_model_config).refiner is None
    clouds = random_clouds(2, 128)
    cloud_index, point_index = torch.tensor([0, 1, 1]), torch.tensor([3, 5, 7])
    condition = model.condition(clouds, cloud_index, point_index)
    anchor = clouds[cloud_index, point_index, :6]
    latent = torch.randn(3, refiner_config.latent_dim)
    decoded = model.decode(latent, condition, anchor)
    assert torch.allclose(model.generate(latent, condition, anchor, clouds, cloud_index), decoded, atol=1e-6)
    with pytest.raises(ValueError, match="point_normals"):
        dataclasses.replace(refiner_config, point_normals=False)


def test_training_the_refiner_brings_its_pose_nearer_the_grasp_than_the_decoders(hand, tiny_assets, make_grasps, refiner_config):
    """On 8 grasps the decoder nearly fits them too, so the refiner's gain is a few percent of an error that moves from epoch
    to epoch (and with the thread schedule): the comparison is of means over the last 10 epochs, summed over 4 training seeds."""
    grasps = make_grasps(hand, 8, seed=1)
    data = build_training_data(grasps, tiny_assets, hand)
    config = TrainConfig(model=refiner_config, epochs=60, max_steps=0, batch_size=8, clouds_per_batch=2, points_per_cloud=64,
                         learning_rate=3e-3, validation_fraction=0.0, energy_warmup_fraction=0.0, weight_kl=1e-3)
    refined, decoded = [], []
    for seed in range(4):
        history = train_cvae(data, np.arange(len(grasps)), np.zeros(0, np.int64), config, unbuilt_energy_terms, seed=seed).history
        assert history[-1][f"train_{REFINE_TERM}"] < 0.5 * history[0][f"train_{REFINE_TERM}"]
        refined.append(np.mean([row[f"train_{REFINE_TERM}"] for row in history[-10:]]))
        decoded.append(np.mean([row["train_recon"] for row in history[-10:]]))
    assert sum(refined) < sum(decoded)  # the correction reads the surface: it improves on the decoder


def test_a_saved_model_keeps_its_refiner(tmp_path, refiner_config):
    from dexlite_pipeline.model.checkpoint import load_checkpoint, save_checkpoint

    torch.manual_seed(0)
    model = GraspCVAE(refiner_config)
    torch.nn.init.normal_(model.refiner[-1].weight, std=0.01)
    path = tmp_path / "cvae.pt"
    save_checkpoint(path, model, TrainConfig(model=refiner_config), {})
    loaded = load_checkpoint(str(path), "cpu")[0]
    assert loaded.config.refiner_hidden == (64, 64)
    assert torch.equal(loaded.refiner[-1].weight, model.refiner[-1].weight)


def test_each_pass_reads_the_surface_again_with_the_same_weights(refiner_config, random_clouds):
    torch.manual_seed(0)
    once = GraspCVAE(refiner_config).eval()
    torch.nn.init.normal_(once.refiner[-1].weight, std=0.01)
    twice = GraspCVAE(dataclasses.replace(refiner_config, refiner_passes=2)).eval()
    twice.load_state_dict(once.state_dict())
    clouds = random_clouds(2, 128)
    cloud_index, point_index = torch.tensor([0, 1]), torch.tensor([3, 5])
    condition = once.condition(clouds, cloud_index, point_index)
    anchor = clouds[cloud_index, point_index, :6]
    decoded = once.decode(torch.randn(2, refiner_config.latent_dim), condition, anchor)
    first = once.refine(decoded, condition, anchor, clouds, cloud_index)
    assert not torch.allclose(first, decoded)
    assert torch.allclose(twice.refine(decoded, condition, anchor, clouds, cloud_index), once.refine(first, condition, anchor, clouds, cloud_index))


def test_a_start_noise_moves_the_refiners_training_and_nothing_without_a_refiner(hand, tiny_assets, make_grasps, refiner_config, small_model_config):
    grasps = make_grasps(hand, 8, seed=1)
    data = build_training_data(grasps, tiny_assets, hand)

    def history(model_config, noise):
        config = TrainConfig(model=model_config, epochs=3, max_steps=0, batch_size=8, clouds_per_batch=2, points_per_cloud=64,
                             learning_rate=3e-3, validation_fraction=0.0, refiner_start_noise_m=noise)
        rows = train_cvae(data, np.arange(len(grasps)), np.zeros(0, np.int64), config, unbuilt_energy_terms, seed=0).history
        return repr([{k: v for k, v in row.items() if k != "seconds"} for row in rows])  # repr: NaN (terms not computed) equals NaN

    assert history(refiner_config, 0.01) != history(refiner_config, 0.0)
    assert history(small_model_config, 0.01) == history(small_model_config, 0.0)
