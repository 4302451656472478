"""Reading prepared assets and catalogs: damage of any kind is an ObjectAssetError naming the object or file."""

import json
import shutil

import pandas as pd
import pytest
import trimesh

from dexlite_pipeline.objects.assets import ObjectAssetError, load_asset, ok_object_ids, read_catalog
from dexlite_pipeline.objects.build import write_asset
from dexlite_pipeline.objects.config import AssetBuildSettings


@pytest.fixture(scope="module")
def good_objects(tmp_path_factory):
    root = tmp_path_factory.mktemp("assets")
    box = trimesh.creation.box(extents=(1.2, 0.8, 0.6))
    write_asset(box, "box", root, AssetBuildSettings(sdf_resolution=16, surface_points=64), {"source": "test"}, convex_pieces=[box])
    return root


def _corrupt_sdf_chunks(arrays):
    for chunk in (arrays / "sdf" / "c").rglob("*"):
        if chunk.is_file():
            chunk.write_bytes(b"not zstd")


def _drop_voxel_size(arrays):
    metadata = json.loads((arrays / "zarr.json").read_text())
    del metadata["attributes"]["voxel_size"]
    (arrays / "zarr.json").write_text(json.dumps(metadata))


DAMAGE = {
    "group_metadata_missing": lambda arrays: (arrays / "zarr.json").unlink(),
    "group_metadata_not_json": lambda arrays: (arrays / "zarr.json").write_text("{"),
    "sdf_array_missing": lambda arrays: shutil.rmtree(arrays / "sdf"),
    "sdf_chunks_corrupt": _corrupt_sdf_chunks,
    "attribute_missing": _drop_voxel_size,
    "meta_not_json": lambda arrays: (arrays.parent / "meta.json").write_text("{not json"),
}


@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_damaged_asset_is_an_object_asset_error_naming_object_and_path(good_objects, tmp_path, damage):
    objects = tmp_path / "objects"
    shutil.copytree(good_objects, objects)
    DAMAGE[damage](objects / "assets" / "box" / "arrays.zarr")
    with pytest.raises(ObjectAssetError, match=r"object 'box'.*assets/box/"):
        load_asset(objects, "box")
    assert load_asset(good_objects, "box").sdf.shape == (16, 16, 16)


def test_asset_with_a_non_cubic_grid_is_refused(good_objects, tmp_path):
    import zarr

    objects = tmp_path / "objects"
    shutil.copytree(good_objects, objects)
    group = zarr.open_group(str(objects / "assets" / "box" / "arrays.zarr"), mode="a")
    del group["sdf"]
    group.create_array("sdf", shape=(16, 16, 8), dtype="float32")
    with pytest.raises(ObjectAssetError, match=r"object 'box'.*sdf \(16, 16, 8\)"):
        load_asset(objects, "box")


def test_catalog_without_a_required_column_names_file_and_column(tmp_path):
    pd.DataFrame({"object_id": ["a"], "split": ["train"]}).to_parquet(tmp_path / "catalog.parquet")
    with pytest.raises(ValueError, match=r"catalog\.parquet: object catalog lacks column\(s\) status"):
        read_catalog(tmp_path)
    (tmp_path / "catalog.parquet").write_text("not parquet")
    with pytest.raises(ValueError, match=r"catalog\.parquet: cannot read the object catalog"):
        read_catalog(tmp_path)
    (tmp_path / "catalog.parquet").unlink()
    with pytest.raises(FileNotFoundError, match=r"catalog\.parquet: object catalog not found \(run prepare_objects first\)"):
        read_catalog(tmp_path)


def test_ok_object_ids_are_pooled_over_catalogs(tmp_path):
    for name, statuses in (("first", {"a": "ok", "b": "rejected"}), ("second", {"c": "ok"})):
        (tmp_path / name).mkdir()
        pd.DataFrame({"object_id": list(statuses), "status": list(statuses.values())}).to_parquet(tmp_path / name / "catalog.parquet")
    assert ok_object_ids([tmp_path / "first", tmp_path / "second"]) == {"a", "c"}
    assert ok_object_ids(tmp_path / "first") == {"a"}
