"""Tiny object assets and grasp sets for the model tests (built once per session in a temp dir)."""

from __future__ import annotations

import pytest
import torch

OBJECT_IDS = ("box", "sphere")
SURFACE_POINTS = 256


@pytest.fixture(autouse=True)
def one_torch_thread():
    """Small tensors run fastest on one thread, and a shared, loaded machine punishes spinning OpenMP workers."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="session")
def tiny_objects(tmp_path_factory):
    """A sphere and a box as prepared assets (coarse SDF grid, few surface samples)."""
    import trimesh

    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    root = tmp_path_factory.mktemp("objects")
    settings = AssetBuildSettings(sdf_resolution=24, surface_points=SURFACE_POINTS)
    meshes = {"sphere": trimesh.creation.icosphere(subdivisions=2, radius=1 / 1.03), "box": trimesh.creation.box(extents=[1.2, 0.9, 0.7])}
    for object_id in OBJECT_IDS:
        write_asset(meshes[object_id], object_id, root, settings, {"source": "test"}, convex_pieces=[meshes[object_id]])
    return root


@pytest.fixture(scope="session")
def tiny_assets(tiny_objects):
    from dexlite_pipeline.objects.assets import load_asset

    return [load_asset(tiny_objects, oid) for oid in OBJECT_IDS]


@pytest.fixture(scope="session")
def make_grasps():
    """``make_grasps(hand, count, seed)``: grasp-like poses on the tiny objects, alternating box and sphere."""
    from demo_grasps import facing_grasps

    return lambda hand, count, seed: facing_grasps(hand, OBJECT_IDS, count, seed)


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
