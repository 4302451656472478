"""The learning ladder's fit rung: training reproduces its own grasps (encoder-mean reconstructions)."""

import numpy as np
import pytest
import torch

from dexlite_pipeline.model.data import build_training_data
from dexlite_pipeline.model.config import TrainConfig
from dexlite_pipeline.model.training import fit_training_codes, train_cvae

FIT_ROTATION_DEG = 3.0  # the ladder's fit targets: median palm rotation and translation error
FIT_TRANSLATION_MM = 5.0


@pytest.fixture(scope="module")
def fixed_dataset(hand, tiny_assets, request):
    """24 fixed grasp-like poses on the box and the sphere (three scales), a tiny stand-in for lift-validated data."""
    grasps = request.getfixturevalue("make_grasps")(hand, 24, seed=3)
    return grasps, build_training_data(grasps, tiny_assets, hand)


def _fit(data, count, config, energy_terms=None):
    everything = np.arange(count)
    result = train_cvae(data, everything, np.zeros(0, np.int64), config, energy_terms, seed=0)
    return result, fit_training_codes(result.model, data, everything, config)


def test_training_reaches_the_fit_rung_on_a_tiny_fixed_dataset(fixed_dataset, small_model_config):
    grasps, data = fixed_dataset
    config = TrainConfig(model=small_model_config, max_steps=1500, batch_size=8, points_per_cloud=64, validation_fraction=0.0)
    result, fit = _fit(data, len(grasps), config)
    assert fit["grasps"] == len(grasps)
    assert fit["rotation_error_deg_median"] <= FIT_ROTATION_DEG, fit
    assert fit["translation_error_mm_median"] <= FIT_TRANSLATION_MM, fit
    assert fit["joint_error_rad_mean"] < 0.05, fit
    # the codes are stored for aggregate-prior sampling, one per training grasp
    assert result.model.latent_codes[0].shape == (len(grasps), small_model_config.latent_dim)
    # PointNet still tells the clouds apart (a dead layer gives every cloud one feature, and the model ignores the object)
    global_feature = result.model.codes_condition[:, : small_model_config.pointnet_widths[-1]]
    clouds = torch.as_tensor(data.cloud_key)
    first_of_cloud = torch.stack([torch.nonzero(clouds == c)[0, 0] for c in torch.unique(clouds)])
    features = global_feature[first_of_cloud]
    distance = torch.cdist(features, features, compute_mode="donot_use_mm_for_euclid_dist")
    off_diagonal = distance[~torch.eye(len(features), dtype=torch.bool)]
    assert off_diagonal.min() > 1e-3 * features.norm(dim=1).mean(), off_diagonal.min()


def test_the_former_recipe_misses_the_fit_rung(fixed_dataset, small_model_config):
    """The same budget with the former recipe: a new random cloud every step (the anchors move), random vertical turns,
    one cloud per batch, a constant learning rate without clipping and a 100x stronger KL term."""
    grasps, data = fixed_dataset
    config = TrainConfig(
        model=small_model_config, max_steps=1500, batch_size=8, points_per_cloud=64, validation_fraction=0.0,
        fixed_clouds=False, rotation_augmentation=True, clouds_per_batch=1, learning_rate=1e-3, lr_schedule="constant",
        lr_warmup_steps=0, grad_clip_norm=0.0, weight_kl=1e-3,
    )
    _, fit = _fit(data, len(grasps), config)
    assert fit["rotation_error_deg_median"] > FIT_ROTATION_DEG or fit["translation_error_mm_median"] > FIT_TRANSLATION_MM, fit
