"""Grasp store schema, round trip and atomic writes."""

import warnings

import numpy as np
import pytest

from dexlite_pipeline.hand import JOINT_NAMES
from dexlite_pipeline.io.grasp_store import GraspSet, GraspStoreError, invalid_grasp_reasons, read_grasp_store, write_grasp_store


def _grasps(n=5):
    rng = np.random.default_rng(0)
    return GraspSet(
        {
            "hand_pose": rng.normal(size=(n, 28)).astype(np.float32),
            "object_id": np.array([f"obj{i % 2}" for i in range(n)], dtype=object),
            "scale": np.full(n, 0.1, np.float32),
            "E_fc": rng.random(n).astype(np.float32),
        }
    )


def test_round_trip(tmp_path):
    path = write_grasp_store(tmp_path / "g.zarr", _grasps(), attrs={"stage": "test"})
    back = read_grasp_store(path)
    original = _grasps()
    np.testing.assert_array_equal(back.hand_pose, original.hand_pose)
    assert list(back.object_id) == list(original.object_id)
    assert back.attrs["joint_names"] == list(JOINT_NAMES)
    assert back.attrs["schema_version"] == 1
    assert back.attrs["stage"] == "test"
    assert not list(tmp_path.glob(".*tmp*"))


def test_snakemake_directory_marker_is_read_quietly(tmp_path):
    path = write_grasp_store(tmp_path / "g.zarr", _grasps(), attrs={})
    (path / ".snakemake_timestamp").touch()  # what Snakemake adds to a directory output
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(read_grasp_store(path)) == 5


def test_empty_store_round_trip(tmp_path):
    write_grasp_store(tmp_path / "e.zarr", _grasps().select(np.zeros(5, bool)))
    assert len(read_grasp_store(tmp_path / "e.zarr")) == 0


def test_wrong_shape_is_refused(tmp_path):
    bad = _grasps()
    bad.arrays["hand_pose"] = bad.arrays["hand_pose"][:, :27]
    with pytest.raises(GraspStoreError, match="expected"):
        write_grasp_store(tmp_path / "bad.zarr", bad)
    assert not (tmp_path / "bad.zarr").exists()


def test_invalid_grasps_are_flagged_not_dropped():
    g = _grasps()
    g.arrays["hand_pose"][1, 3] = np.nan
    g.arrays["scale"][2] = -1
    reasons = invalid_grasp_reasons(g, known_object_ids={"obj0"})
    assert reasons[0] == ""
    assert "non-finite" in reasons[1]
    assert "scale" in reasons[2]
    assert "object id" in reasons[3]


def test_grasp_type_round_trips_and_defaults_to_power(tmp_path):
    from dexlite_pipeline.io.grasp_store import grasp_types

    typed = _grasps(4)
    typed.arrays["grasp_type"] = np.array(["power", "pinch", "tripod", "lateral"], dtype=object)
    back = read_grasp_store(write_grasp_store(tmp_path / "typed.zarr", typed))
    assert grasp_types(back).tolist() == ["power", "pinch", "tripod", "lateral"]
    older = read_grasp_store(write_grasp_store(tmp_path / "older.zarr", _grasps(3)))  # written before grasp types existed
    assert "grasp_type" not in older.arrays and grasp_types(older).tolist() == ["power"] * 3


def test_concatenating_typed_and_untyped_grasps_keeps_the_types():
    """Curation joins optimized shards (typed) with imported grasps (untyped): the imported ones are power grasps."""
    typed = _grasps(2)
    typed.arrays["grasp_type"] = np.array(["pinch", "lateral"], dtype=object)
    joined, left_out = GraspSet.concatenate_common([typed, _grasps(3)])
    assert left_out == []
    assert joined.arrays["grasp_type"].tolist() == ["pinch", "lateral", "power", "power", "power"]
    untyped, _ = GraspSet.concatenate_common([_grasps(2), _grasps(1)])
    assert "grasp_type" not in untyped.arrays
