"""Tiny object assets and grasp sets for the model tests (built once per session in a temp dir)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix, matrix_to_euler_xyz
from dexlite_pipeline.io.grasp_store import GraspSet

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

    from dexlite_pipeline.objects.build import AssetBuildSettings, write_asset

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


def wrapping_grasps(hand, count: int, seed: int, object_ids=OBJECT_IDS) -> GraspSet:
    """Grasp-like poses: the palm facing the object just off its surface, fingers half closed.

    The object centre sits in front of the palm (palm frame −y), so the pads face it;
    random palm orientations about the object, scales from DexGraspNet's set.
    """
    rng = np.random.default_rng(seed)
    scale = rng.choice([0.06, 0.08, 0.1], count).astype(np.float32)
    rotation = euler_xyz_to_matrix(torch.as_tensor(rng.uniform(-np.pi, np.pi, (count, 3)), dtype=torch.float32))
    centre_in_palm = torch.stack(
        [torch.full((count,), 0.01), -(torch.as_tensor(scale) + 0.015), torch.full((count,), 0.07)], dim=1
    )
    translation = -(rotation @ centre_in_palm[:, :, None])[:, :, 0]
    limits = hand.joint_limits
    joints = limits[:, 0] + (limits[:, 1] - limits[:, 0]) * torch.as_tensor(rng.uniform(0.3, 0.5, (count, 22)), dtype=torch.float32)
    pose = torch.cat([translation, matrix_to_euler_xyz(rotation), joints], dim=1).numpy()
    objects = np.asarray([object_ids[i % len(object_ids)] for i in range(count)], dtype=object)
    return GraspSet({"hand_pose": pose, "object_id": objects, "scale": scale})


@pytest.fixture(scope="session")
def make_grasps():
    """``make_grasps(hand, count, seed)``: grasp-like poses on the tiny objects (see ``wrapping_grasps``)."""
    return wrapping_grasps


@pytest.fixture
def small_model_config():
    from dexlite_pipeline.model.network import ModelConfig

    return ModelConfig(pointnet_widths=(16, 32, 64, 32), encoder_hidden=(64, 64), decoder_hidden=(64, 64), latent_dim=8, normalization="none")
