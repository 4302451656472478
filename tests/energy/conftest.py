"""Tiny object assets for the energy and optimizer tests (low SDF resolution, built in tmp)."""

from __future__ import annotations

import pytest


def build_assets(objects_dir, meshes: dict, resolution: int = 40, surface_points: int = 1500) -> None:
    """Write one asset per (id -> trimesh) with its own mesh as the only convex piece."""
    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    settings = AssetBuildSettings(sdf_resolution=resolution, sdf_padding=0.3, surface_points=surface_points)
    for object_id, mesh in meshes.items():
        write_asset(mesh, object_id, objects_dir, settings, {"source": "test"}, convex_pieces=[mesh])


@pytest.fixture(scope="session")
def sphere_objects(tmp_path_factory):
    """An objects dir holding a unit sphere ('sphere') and a box ('box'), normalized units."""
    import trimesh

    root = tmp_path_factory.mktemp("energy_objects")
    build_assets(
        root,
        {
            "sphere": trimesh.creation.icosphere(subdivisions=4, radius=1.0),
            "box": trimesh.creation.box(extents=(1.2, 0.8, 0.6)),
        },
    )
    return root


@pytest.fixture(scope="session")
def fine_sphere_objects(tmp_path_factory):
    """A unit sphere ('sphere') with a fine SDF and dense surface points: small interpolation bounds in culling."""
    import trimesh

    root = tmp_path_factory.mktemp("fine_sphere_objects")
    build_assets(root, {"sphere": trimesh.creation.icosphere(subdivisions=4, radius=1.0)}, resolution=96, surface_points=4096)
    return root


@pytest.fixture(autouse=True, scope="module")
def single_thread():
    """Small batched torch ops run fastest on one thread (and the machine is shared); restored after."""
    import torch

    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)
