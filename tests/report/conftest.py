"""Fixture: one prepared object (a box) with a catalog marking it held out."""

import pandas as pd
import pytest
from report_synthetic import OBJECT_ID


@pytest.fixture(scope="session")
def tiny_objects(tmp_path_factory):
    """One prepared object (a box, normalized size) with a catalog marking it held out."""
    import trimesh

    from dexlite_pipeline.objects.build import AssetBuildSettings, write_asset

    root = tmp_path_factory.mktemp("objects")
    mesh = trimesh.creation.box(extents=(1.2, 0.8, 0.6))
    write_asset(mesh, OBJECT_ID, root, AssetBuildSettings(sdf_resolution=16, surface_points=128), {"source": "test"}, convex_pieces=[mesh])
    pd.DataFrame({"object_id": [OBJECT_ID, "train_obj"], "split": ["heldout", "train"], "status": ["ok", "ok"]}).to_parquet(root / "catalog.parquet")
    return root
