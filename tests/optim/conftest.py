"""Tiny objects for the optimizer and optimize-stage tests (coarse SDF, the mesh as its own convex piece)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def optim_objects(tmp_path_factory):
    """An objects dir with a sphere and a box (normalized units) and a catalog of both."""
    import pandas as pd
    import trimesh

    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    root = tmp_path_factory.mktemp("optim_objects")
    settings = AssetBuildSettings(sdf_resolution=32, sdf_padding=0.3, surface_points=800)
    meshes = {"sphere": trimesh.creation.icosphere(subdivisions=3, radius=1.0), "box": trimesh.creation.box(extents=(1.2, 0.8, 0.6))}
    rows = []
    for object_id, mesh in meshes.items():
        summary = write_asset(mesh, object_id, root, settings, {"source": "test"}, convex_pieces=[mesh])
        rows.append({**summary, "source": "test", "file": f"{object_id}.obj", "status": "ok", "reason": "", "split": "train"})
    pd.DataFrame(rows).to_parquet(root / "catalog.parquet")
    return root

