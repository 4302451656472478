"""objects.dataset_collision false: dataset objects prepared without collision pieces, standing in the recorded pose."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import trimesh

from dexlite_pipeline.objects.assets import asset_dir, load_asset
from dexlite_pipeline.objects.config import ObjectsConfig, StabilityConfig
from dexlite_pipeline.objects.prepare import _build_key, prepare_object
from dexlite_pipeline.objects.rest_pose import REST_POSE_COLUMNS, RecordedRest
from dexlite_pipeline.objects.sources import MeshSource, collect_sources
from dexlite_pipeline.objects.stability import RECORDED_REASON, simulate_asset

REPO = Path(__file__).resolve().parents[2]
# Small grids and a light CoACD search keep the full preparation, the reference here, at about a second.
TINY = ObjectsConfig(builtin_count=0, benchmark_objects=0, sdf_resolution=20, sdf_exact_band=0.2, surface_points=128,
                     coacd_mcts_iterations=10, coacd_mcts_nodes=5, coacd_mcts_max_depth=1, coacd_resolution=300)
STABILITY = StabilityConfig()


def _box_source(tmp_path) -> MeshSource:
    path = tmp_path / "box.obj"
    trimesh.creation.box((0.06, 0.04, 0.1)).export(path)
    return MeshSource("user-box", "user", str(path), metres_per_unit=1.0)


def test_a_recorded_pose_skips_the_decomposition_and_the_object_stands_in_it(tmp_path):
    """The full preparation and its drop give a resting pose; the same mesh prepared with that pose recorded has no
    convex pieces, another reuse key, the pose in its meta.json, and a stability row that is that pose, stable."""
    source = _box_source(tmp_path)
    settings = TINY.build_settings(0)
    full_dir, light_dir = tmp_path / "full", tmp_path / "light"
    assert prepare_object(source, str(full_dir), settings)["n_convex_pieces"] >= 1
    full = simulate_asset(("user-box", str(asset_dir(full_dir, "user-box"))), STABILITY, 0)
    assert full["stable"] and full["reason"] == ""

    light_source = dataclasses.replace(source, recorded_rest=RecordedRest.from_row(full))
    row = prepare_object(light_source, str(light_dir), settings)
    assert row["status"] == "ok" and row["n_convex_pieces"] == 0
    asset = load_asset([str(light_dir)], "user-box")
    assert asset.convex_paths == [] and len(load_asset([str(full_dir)], "user-box").convex_paths) >= 1
    meta = json.loads((asset.directory / "meta.json").read_text())
    assert RecordedRest.from_dict(meta["recorded_rest_pose"]) == RecordedRest.from_row(full)
    assert _build_key(light_source, settings, "") != _build_key(source, settings, "")

    light = simulate_asset(("user-box", str(asset.directory)), STABILITY, 0)
    assert light["stable"] and light["reason"] == RECORDED_REASON
    assert math.isnan(light["lateral_displacement_m"]) and math.isnan(light["rotation_deg"])
    for column in REST_POSE_COLUMNS:
        assert light[column] == pytest.approx(full[column], abs=1e-9 if column != "rest_height_m" else 0.002), column
    # what the learning stages read (surface samples, signed distances) is the full asset's, bit for bit
    reference = load_asset([str(full_dir)], "user-box")
    np.testing.assert_array_equal(asset.surface_points, reference.surface_points)
    np.testing.assert_array_equal(asset.surface_normals, reference.surface_normals)
    np.testing.assert_array_equal(asset.sdf, reference.sdf)


def test_a_recorded_pose_that_does_not_fit_the_mesh_is_not_stable_and_says_why(tmp_path):
    source = _box_source(tmp_path)
    upright = RecordedRest((0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 1.0), 0.0)  # the origin on the table: the box half inside it
    prepare_object(dataclasses.replace(source, recorded_rest=upright), str(tmp_path / "light"), TINY.build_settings(0))
    row = simulate_asset(("user-box", str(asset_dir(tmp_path / "light", "user-box"))), STABILITY, 0)
    assert not row["stable"] and "does not fit the prepared mesh" in row["reason"]
    assert all(math.isnan(row[c]) for c in REST_POSE_COLUMNS)


def test_an_object_without_collision_pieces_cannot_be_simulated_and_the_reason_says_so():
    from dexlite_pipeline.sim.config import LiftConfig
    from dexlite_pipeline.sim.scene import LiftScene, SceneBuildError

    with pytest.raises(SceneBuildError, match="objects.dataset_collision"):
        LiftScene.build([], 0.1, LiftConfig())


def test_the_stage_takes_each_objects_pose_from_the_repositorys_dataset():
    from dexlite_pipeline.stages.prepare_objects import dataset_rest_poses

    table = pd.read_csv(REPO / "dataset" / "objects.csv").drop_duplicates("object_id").set_index("object_id")
    wanted = list(table.index[:3])
    rests = dataset_rest_poses(str(REPO / "dataset"), [*wanted, "household-mug-999"])
    assert sorted(rests) == sorted(wanted)
    for object_id in wanted:
        row = table.loc[object_id]
        assert rests[object_id].quaternion_xyzw == pytest.approx([row[c] for c in ("rest_qx", "rest_qy", "rest_qz", "rest_qw")])
        assert rests[object_id].support_offset == pytest.approx(row["support_offset"])


def test_a_row_without_a_table_records_no_pose():
    row = {"rest_qx": 0.0, "rest_qy": 0.0, "rest_qz": 0.0, "rest_qw": 1.0, "support_nx": float("nan"), "support_ny": 0.0,
           "support_nz": 1.0, "support_offset": 0.5}
    assert RecordedRest.from_row(row) is None and RecordedRest.from_row({}) is None


def test_only_the_dataset_objects_given_a_pose_are_prepared_without_pieces(tmp_path):
    rest = RecordedRest((0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 1.0), 0.5)
    sources = collect_sources(0, [], [], seed=0, household_count=1, household_first=3, household_families=("mug",),
                              household_dir=tmp_path / "meshes", rebuilt_training_ids=("household-mug-000", "household-mug-001"),
                              rebuilt_rests={"household-mug-000": rest, "household-mug-003": rest})
    by_id = {s.object_id: s.recorded_rest for s in sources}
    # mug 003 is drawn by household_count, not rebuilt from the dataset: prepared in full like mug 001 (no pose given)
    assert by_id == {"household-mug-003": None, "household-mug-000": rest, "household-mug-001": None}
