"""Stability filter: shapes whose answer is known, the centre-of-mass pitfall, determinism, the stage."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import trimesh

from dexlite_pipeline.objects.build import write_asset
from dexlite_pipeline.objects.config import AssetBuildSettings
from dexlite_pipeline.objects.asset_building import normalize_mesh
from dexlite_pipeline.objects.config import StabilityConfig
from dexlite_pipeline.objects.stability import STABILITY_COLUMNS, simulate_object, stability_table, tilt_rotation

CONFIG = StabilityConfig()


def _flip(mesh):
    """Upside down (rotated 180 degrees about x)."""
    mesh = mesh.copy()
    mesh.apply_transform(trimesh.transformations.rotation_matrix(math.pi, [1, 0, 0]))
    return mesh


SHAPES = {
    "cube": (trimesh.creation.box((1.0, 1.0, 1.0)), True),
    "cone_on_base": (trimesh.creation.cone(0.5, 1.0, sections=32), True),
    "squat_cylinder": (trimesh.creation.cylinder(0.4, 0.5, sections=32), True),
    "cone_on_tip": (_flip(trimesh.creation.cone(0.5, 1.0, sections=32)), False),
    # 3 degrees of tilt topple a cylinder whose radius is under tan(3 deg) = 0.052 of its half height.
    "thin_cylinder_on_end": (trimesh.creation.cylinder(0.015, 1.0, sections=16), False),
}


def _simulate(tmp_path, name, mesh, seed=0, shift=(0.0, 0.0, 0.0)):
    mesh = normalize_mesh(mesh)[0]
    mesh.apply_translation(shift)
    piece = tmp_path / f"{name}.obj"
    mesh.export(piece)
    return simulate_object(mesh, [piece], name, CONFIG, seed)


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_known_shapes(tmp_path, name):
    mesh, expected = SHAPES[name]
    result = _simulate(tmp_path, name, mesh)
    assert result.stable is expected, result
    if expected:
        assert result.reason == "" and result.lateral_displacement_m < 0.01 and result.rotation_deg < 5
    else:
        assert result.reason.startswith("unstable:") and result.rotation_deg > 30


def test_true_centre_of_mass_is_used_not_the_mesh_origin(tmp_path):
    """A rod whose mesh origin is the centre of its bottom face: with the centre of mass taken at
    the origin (PyBullet's default) it would right itself from the tilt and pass (checked by
    hand); with the true centre of mass, halfway up, it topples."""
    rod, _ = SHAPES["thin_cylinder_on_end"]
    half_height = normalize_mesh(rod)[0].bounds[1, 2]
    base_origin = _simulate(tmp_path, "rod_base_origin", rod, shift=(0.0, 0.0, half_height))
    assert not base_origin.stable and base_origin.rotation_deg > 30


def test_deterministic_and_tilt_is_seeded(tmp_path):
    mesh, _ = SHAPES["thin_cylinder_on_end"]
    first = _simulate(tmp_path, "rod", mesh, seed=5)
    assert _simulate(tmp_path, "rod", mesh, seed=5) == first
    tilts = [tilt_rotation("rod", 3.0, seed) for seed in (5, 6)]
    for tilt in tilts:
        assert math.degrees(math.acos((np.trace(tilt) - 1) / 2)) == pytest.approx(3.0)
        assert abs(tilt[2, 2] - math.cos(math.radians(3.0))) < 1e-12  # the axis is horizontal
    assert not np.allclose(tilts[0], tilts[1])


def test_table_carries_rejected_objects_and_stage_writes_it(tmp_path):
    objects = tmp_path / "objects"
    settings = AssetBuildSettings(sdf_resolution=16, surface_points=64)
    for name in ("cube", "cone_on_tip"):
        mesh = normalize_mesh(SHAPES[name][0])[0]
        write_asset(mesh, name, objects, settings, {"source": "test"}, convex_pieces=[mesh])
    catalog = pd.DataFrame(
        {
            "object_id": ["cube", "cone_on_tip", "broken"],
            "source": "test", "file": "", "watertight": [True, True, False], "volume": [1.0, 1.0, np.nan],
            "n_convex_pieces": [1, 1, 0], "status": ["ok", "ok", "rejected"],
            "reason": ["", "", "not watertight after repair: 3 boundary edges, 0 non-manifold edges"], "split": ["train", "train", ""],
        }
    )
    catalog.to_parquet(objects / "catalog.parquet", index=False)
    table = stability_table(catalog, [str(objects)], CONFIG, seed=0, workers=0).set_index("object_id")
    assert bool(table.loc["cube", "stable"]) and not bool(table.loc["cone_on_tip", "stable"])
    assert not bool(table.loc["broken", "stable"]) and "not watertight" in table.loc["broken", "reason"]
    assert math.isnan(table.loc["broken", "rotation_deg"])

    from dexlite_pipeline.cli import main

    out = tmp_path / "stability" / "stability.parquet"
    cfg = json.dumps({"seed": 0, "stability": {"duration_s": 1.0}})
    assert main(["stability-filter", "--config-json", cfg, "--objects", str(objects), "--out", str(out), "--record", str(out.parent / "stability_config.json"), "--threads", "1"]) == 0
    written = pd.read_parquet(out)
    assert list(written.columns) == STABILITY_COLUMNS
    assert written.set_index("object_id")["stable"].to_dict() == {"broken": False, "cone_on_tip": False, "cube": True}
    assert json.loads((out.parent / "stability_config.json").read_text())["stability"]["duration_s"] == 1.0


def test_malformed_stability_table_is_a_one_line_error_naming_file_and_problem(tmp_path):
    from dexlite_pipeline.objects.stability import read_stability_table, stable_object_ids

    path = tmp_path / "stability.parquet"
    with pytest.raises(FileNotFoundError, match="stability.parquet: stability table not found"):
        read_stability_table(path)
    pd.DataFrame({"object_id": ["a"], "is_stable": [True]}).to_parquet(path)
    with pytest.raises(ValueError, match=r"stability.parquet: stability table lacks column\(s\) stable"):
        read_stability_table(path)
    pd.DataFrame({"object_id": ["a"], "stable": ["False"]}).to_parquet(path)  # a string is truthy: refused, not read as stable
    with pytest.raises(ValueError, match="stability.parquet: stability column 'stable' holds .*, expected true/false"):
        read_stability_table(path)
    path.write_text("not parquet")
    with pytest.raises(ValueError, match="stability.parquet: cannot read the stability table"):
        read_stability_table(path)
    pd.DataFrame({"object_id": ["a", "b"], "stable": [True, False]}).to_parquet(path)
    assert stable_object_ids(path) == {"a"}


def test_stage_refuses_a_catalog_without_status_in_one_line(tmp_path, capsys):
    from dexlite_pipeline.cli import main

    objects = tmp_path / "objects"
    objects.mkdir()
    pd.DataFrame({"object_id": ["cube"], "split": ["train"]}).to_parquet(objects / "catalog.parquet")
    assert main(["stability-filter", "--objects", str(objects), "--out", str(tmp_path / "stability.parquet"), "--record", str(tmp_path / "record.json"), "--threads", "1"]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "catalog.parquet" in error and "status" in error
    assert not (tmp_path / "stability.parquet").exists()


def test_stability_filter_fails_when_no_object_was_prepared(tmp_path, caplog):
    from dexlite_pipeline.cli import main

    objects = tmp_path / "objects"
    objects.mkdir()
    pd.DataFrame({"object_id": ["a", "b"], "status": ["rejected", "rejected"], "reason": ["empty mesh", "flat"]}).to_parquet(objects / "catalog.parquet")
    assert main(["stability-filter", "--objects", str(objects), "--out", str(tmp_path / "stability.parquet"), "--record", str(tmp_path / "record.json"), "--threads", "1"]) == 1
    assert "no prepared object to test" in caplog.text
    assert not (tmp_path / "stability.parquet").exists()


def test_pybullet_is_imported_without_its_banner():
    code = "from dexlite_pipeline.objects.stability import import_pybullet; import_pybullet(); print('done')"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout == "done\n" and "pybullet build time" not in result.stderr


@pytest.mark.parametrize("name", ["cube", "squat_cylinder", "cone_on_tip"])
def test_resting_pose_is_recorded_and_agrees_with_the_simulated_height(tmp_path, name):
    """The recorded support plane is the table seen from the object: its normal is the world's +z
    carried back by the resting rotation, the lowest vertex lies on it, and the mesh origin's height
    above it (geometry: offset x scale) matches the height PyBullet settled the object at. A stable
    shape rests within a few degrees of its file orientation; the toppled cone rests on its side."""
    from scipy.spatial.transform import Rotation

    from dexlite_pipeline.objects.rest_pose import REST_POSE_COLUMNS
    from dexlite_pipeline.tabletop import plane_from_row

    mesh = normalize_mesh(SHAPES[name][0])[0]
    row = _simulate(tmp_path, name, SHAPES[name][0]).row()
    assert all(math.isfinite(row[c]) for c in REST_POSE_COLUMNS)
    plane = plane_from_row(row)
    normal = np.asarray(plane.normal)
    rotation = Rotation.from_quat([row["rest_qx"], row["rest_qy"], row["rest_qz"], row["rest_qw"]]).as_matrix()
    np.testing.assert_allclose(rotation.T @ [0, 0, 1], normal, atol=1e-9)
    heights = np.asarray(mesh.vertices) @ normal + plane.offset
    assert heights.min() == pytest.approx(0.0, abs=1e-9)
    assert row["rest_height_m"] == pytest.approx(plane.offset * CONFIG.scale, abs=0.002)
    tilt_deg = math.degrees(math.acos(min(1.0, normal[2])))
    assert (tilt_deg < 5.0) if SHAPES[name][1] else (tilt_deg > 45.0)


def test_unsimulated_rows_have_no_resting_pose():
    from dexlite_pipeline.objects.stability import StabilityResult
    from dexlite_pipeline.objects.rest_pose import REST_POSE_COLUMNS
    from dexlite_pipeline.tabletop import plane_from_row

    row = StabilityResult("x", math.nan, math.nan, False, "not simulated").row()
    assert all(math.isnan(row[c]) for c in REST_POSE_COLUMNS) and plane_from_row(row) is None


def test_settle_uses_the_pose_an_object_comes_to_rest_in(tmp_path):
    """A box balanced on an edge falls onto a face: unstable in its file orientation; with ``settle`` it is dropped
    again from where it came to rest, stands there, and its support plane is that face. A box standing on a face is
    judged by its first drop alone, identically with and without ``settle``."""
    import dataclasses

    from dexlite_pipeline.objects.rest_pose import SUPPORT_NORMAL_COLUMNS

    on_edge = trimesh.creation.box((1.0, 0.6, 0.3))
    on_edge.apply_transform(trimesh.transformations.rotation_matrix(math.radians(45), [1, 0, 0]))
    mesh = normalize_mesh(on_edge)[0]
    piece = tmp_path / "edge.obj"
    mesh.export(piece)
    first = simulate_object(mesh, [piece], "edge", CONFIG, 0)
    assert not first.stable and not first.settled
    settled = simulate_object(mesh, [piece], "edge", dataclasses.replace(CONFIG, settle=True), 0)
    assert settled.stable and settled.settled and settled.reason == "" and settled.object_id == "edge"
    normal = np.array([settled.rest_pose[c] for c in SUPPORT_NORMAL_COLUMNS])
    # the table's normal in the object frame is one of the box's face normals (turned 45 deg about x), not +z
    faces = trimesh.transformations.rotation_matrix(math.radians(45), [1, 0, 0])[:3, :3] @ np.vstack([np.eye(3), -np.eye(3)]).T
    assert np.max(faces.T @ normal) > 0.99 and normal[2] < 0.9
    assert settled.row()["settled"] is True

    cube = trimesh.creation.box((1.0, 1.0, 1.0))
    plain = _simulate(tmp_path, "cube", cube)
    again = simulate_object(normalize_mesh(cube)[0], [tmp_path / "cube.obj"], "cube", dataclasses.replace(CONFIG, settle=True), 0)
    assert plain == again and not again.settled
