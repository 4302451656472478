"""Small model configurations and random point clouds for the model tests; every model test runs on one torch thread.

The sphere and box assets and the grasp-like poses on them are in tests/conftest.py (the optimizer tests use them too).
"""

from __future__ import annotations

import pytest
import torch


@pytest.fixture(autouse=True)
def model_tests_on_one_thread(one_torch_thread):
    """Every model test runs on one torch thread (``one_torch_thread``)."""


@pytest.fixture
def small_model_config():
    from dexlite_pipeline.model.config import ModelConfig

    return ModelConfig(pointnet_widths=(16, 32, 64, 32), encoder_hidden=(64, 64), decoder_hidden=(64, 64), latent_dim=8, normalization="none")


@pytest.fixture(scope="session")
def random_clouds():
    """``random_clouds(count, points)``: (count, points, 6) clouds in the model's layout, positions ~0.1 m, unit normals."""

    def make(count: int, points: int):
        positions = torch.randn(count, points, 3) * 0.1
        return torch.cat([positions, torch.nn.functional.normalize(torch.randn(count, points, 3), dim=-1)], dim=2)

    return make
