"""Object preparation: rejection reasons, repair, normalization, catalog, split, reuse."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import trimesh

from dexlite_pipeline.objects.assets import CATALOG_COLUMNS, load_asset
from dexlite_pipeline.objects.config import ObjectsConfig
from dexlite_pipeline.objects.asset_building import MeshRejected, check_mesh, normalize_mesh, prepared_solid
from dexlite_pipeline.objects.prepare import assign_split, heldout_ids, heldout_turn_deg, prepare_object, prepare_objects, turned_heldout
from dexlite_pipeline.objects.sources import MeshSource, collect_sources

# Small grids, few samples and a light CoACD search keep these tests at a second or two.
TINY = ObjectsConfig(
    builtin_count=0, benchmark_objects=0, sdf_resolution=20, sdf_exact_band=0.2, surface_points=128,
    coacd_mcts_iterations=10, coacd_mcts_nodes=5, coacd_mcts_max_depth=1, coacd_resolution=300,
)


def _obj_text(vertices, faces) -> str:
    lines = [f"v {x} {y} {z}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    return "\n".join(lines) + "\n"


TET_VERTICES = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
TET_FACES = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]

BAD_MESHES = {
    "unreadable": ("bad_index.obj", "v 0 0 0\nv 1 0 0\nf 1 2 9\n"),
    "unreadable: no mesh data": ("noise.obj", "\x00\x01binary noise that is not a mesh\x02"),
    "empty mesh": ("empty.obj", ""),
    "non-finite vertices": ("nan.obj", _obj_text([(0, 0, 0), (1, 0, 0), (0, 1, 0), ("nan", 0, 1)], TET_FACES)),
    "degenerate: flat": ("flat.obj", _obj_text([(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], [(0, 1, 2), (1, 3, 2)])),
    "degenerate: only 2": ("folded.obj", _obj_text([(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 0, 1)], [(0, 1, 2), (0, 3, 1)])),
}
# Two closed tetrahedra sharing one edge (four faces on it): one object of two bodies that touch.
BOWTIE = _obj_text(TET_VERTICES + [(0, -1, 0), (0, 0, -1)], TET_FACES + [(0, 1, 4), (0, 5, 1), (0, 4, 5), (1, 5, 4)])


def test_two_closed_bodies_touching_along_an_edge_are_one_object(tmp_path):
    path = tmp_path / "bowtie.obj"
    path.write_text(BOWTIE)
    row = prepare_object(MeshSource("user-bowtie", "user", str(path)), str(tmp_path / "out"), TINY.build_settings(0))
    assert row["status"] == "ok", row["reason"]
    assert row["volume_ratio"] == pytest.approx(1.0, abs=0.05)
    assert row["surface_deviation"] < 0.02 and row["bounds_deviation"] < 0.02


@pytest.mark.parametrize("reason", sorted(BAD_MESHES))
def test_each_bad_mesh_is_rejected_with_its_reason(tmp_path, reason):
    name, text = BAD_MESHES[reason]
    path = tmp_path / name
    path.write_text(text)
    row = prepare_object(MeshSource("user-bad", "user", str(path)), str(tmp_path / "out"), TINY.build_settings(0))
    assert row["status"] == "rejected"
    assert row["reason"].startswith(reason), row["reason"]
    assert "\n" not in row["reason"]
    assert not (tmp_path / "out" / "assets" / "user-bad").exists()


def test_hole_is_filled_and_inverted_winding_fixed():
    cylinder = trimesh.creation.cylinder(radius=0.5, height=1.0, sections=24)
    top_cap = cylinder.triangles_center[:, 2] > 0.49
    assert top_cap.sum() >= 20  # a 24-gon hole: too large for trimesh's own fill_holes
    open_cylinder = trimesh.Trimesh(cylinder.vertices, cylinder.faces[~top_cap][:, ::-1], process=False)
    assert not open_cylinder.is_watertight
    repaired = prepared_solid(open_cylinder)[0]
    check_mesh(repaired)
    assert repaired.is_watertight and repaired.volume > 0
    assert repaired.volume == pytest.approx(cylinder.volume, rel=0.02)


def test_overlapping_shells_become_one_solid():
    a = trimesh.creation.box((1.0, 1.0, 1.0))
    b = trimesh.creation.box((1.0, 1.0, 1.0))
    b.apply_translation((0.5, 0, 0))
    repaired = prepared_solid(trimesh.util.concatenate([a, b]))[0]
    assert repaired.body_count == 1
    assert repaired.volume == pytest.approx(1.5, rel=1e-6)


def test_normalization_centres_bounding_box_and_sets_radius():
    box = trimesh.creation.box((3.0, 1.0, 0.5))
    box.apply_translation((10.0, -4.0, 2.0))
    normalized, centre, factor = normalize_mesh(box)
    np.testing.assert_allclose(centre, (10.0, -4.0, 2.0), atol=1e-12)
    np.testing.assert_allclose(normalized.bounds.mean(axis=0), 0.0, atol=1e-12)
    assert np.linalg.norm(normalized.vertices, axis=1).max() == pytest.approx(1 / 1.03)
    with pytest.raises(MeshRejected, match="degenerate"):
        check_mesh(trimesh.Trimesh(box.vertices[:3], [[0, 1, 2]]))


def _write_user_meshes(folder):
    folder.mkdir()
    trimesh.creation.box((1.0, 0.6, 0.4)).export(folder / "box.obj")
    trimesh.creation.icosphere(subdivisions=2).export(folder / "ball.stl")
    (folder / "broken.obj").write_text("v 0 0 0\nf 1 2 3\n")


def test_prepare_objects_writes_catalog_assets_and_config(tmp_path):
    _write_user_meshes(tmp_path / "mine")
    (tmp_path / "eval").mkdir()
    trimesh.creation.cylinder(radius=0.3, height=1.0).export(tmp_path / "eval" / "can.obj")
    config = ObjectsConfig(**{**TINY.__dict__, "mesh_dirs": (str(tmp_path / "mine"),), "heldout_mesh_dirs": (str(tmp_path / "eval"),)})
    sources = collect_sources(0, config.mesh_dirs, config.heldout_mesh_dirs, seed=0)
    out = tmp_path / "objects"
    catalog = prepare_objects(sources, out, config, seed=0, workers=0)

    stored = pd.read_parquet(out / "catalog.parquet")
    assert list(stored.columns) == list(CATALOG_COLUMNS)
    pd.testing.assert_frame_equal(stored, catalog)
    rows = stored.set_index("object_id")
    assert set(rows.index) == {"user-box", "user-ball", "user-broken", "user-can"}
    assert rows.loc["user-broken", "status"] == "rejected" and rows.loc["user-broken", "split"] == ""
    for oid in ("user-box", "user-ball", "user-can"):
        assert rows.loc[oid, "status"] == "ok" and rows.loc[oid, "reason"] == ""
        assert bool(rows.loc[oid, "watertight"]) and rows.loc[oid, "n_convex_pieces"] >= 1
        assert (out / "assets" / oid / "arrays.zarr").exists()
    assert rows.loc["user-can", "split"] == "heldout" and rows.loc["user-can", "source"] == "user_heldout"
    assert rows.loc["user-box", "volume"] == pytest.approx(1.0 * 0.6 * 0.4 / (np.linalg.norm([0.5, 0.3, 0.2]) * 1.03) ** 3)
    recorded = json.loads((out / "prepare_config.json").read_text())
    assert recorded["seed"] == 0 and recorded["objects"]["sdf_resolution"] == TINY.sdf_resolution


def test_unchanged_assets_are_reused_and_stale_ones_removed(tmp_path):
    _write_user_meshes(tmp_path / "mine")
    config = ObjectsConfig(**{**TINY.__dict__, "mesh_dirs": (str(tmp_path / "mine"),)})
    out = tmp_path / "objects"
    prepare_objects(collect_sources(0, config.mesh_dirs, (), 0), out, config, seed=0, workers=0)
    arrays = out / "assets" / "user-box" / "arrays.zarr"
    before = arrays.stat().st_mtime_ns
    (tmp_path / "mine" / "ball.stl").unlink()
    again = prepare_objects(collect_sources(0, config.mesh_dirs, (), 0), out, config, seed=0, workers=0)
    assert arrays.stat().st_mtime_ns == before
    assert not (out / "assets" / "user-ball").exists()
    assert set(again["object_id"]) == {"user-box", "user-broken"}
    changed = ObjectsConfig(**{**config.__dict__, "surface_points": 64})
    prepare_objects(collect_sources(0, config.mesh_dirs, (), 0), out, changed, seed=0, workers=0)
    assert arrays.stat().st_mtime_ns != before
    box = MeshSource("user-box", "user", str(tmp_path / "mine" / "box.obj"))
    prepare_object(box, str(out), changed.build_settings(0), builder="v1")
    built = arrays.stat().st_mtime_ns
    prepare_object(box, str(out), changed.build_settings(0), builder="v1")
    assert arrays.stat().st_mtime_ns == built
    prepare_object(box, str(out), changed.build_settings(0), builder="v2")  # changed code: rebuilt
    assert arrays.stat().st_mtime_ns != built


def test_a_shared_asset_cache_gives_another_run_the_same_assets_without_building_them(tmp_path, monkeypatch, caplog):
    import logging

    import dexlite_pipeline.objects.asset_building as asset_building

    _write_user_meshes(tmp_path / "mine")
    cache = tmp_path / "cache"
    config = ObjectsConfig(**{**TINY.__dict__, "mesh_dirs": (str(tmp_path / "mine"),), "asset_cache": str(cache)})
    sources = collect_sources(0, config.mesh_dirs, (), 0)
    first = prepare_objects(sources, tmp_path / "run_a", config, seed=0, workers=0)
    assert sorted(p.name for p in cache.iterdir()) == ["user-ball", "user-box"]  # built ok: cached; rejected: not

    def no_building(*args, **kwargs):
        raise AssertionError("an asset in the cache was built again")

    monkeypatch.setattr(asset_building, "write_asset", no_building)
    caplog.set_level(logging.INFO, logger="dexlite_pipeline.objects.prepare")
    second = prepare_objects(sources, tmp_path / "run_b", config, seed=0, workers=0)
    assert f"2 of 3 objects already built (in {tmp_path / 'run_b'} or the asset cache), 1 to build" in caplog.text
    assert "preparation: 3/3 objects (100%; 2 reused)" in caplog.text  # the rejected mesh is the one worked on
    pd.testing.assert_frame_equal(first, second)
    a, b = load_asset([str(tmp_path / "run_a")], "user-box"), load_asset([str(tmp_path / "run_b")], "user-box")
    np.testing.assert_array_equal(a.surface_points, b.surface_points)
    assert a.meta["build_key"] == b.meta["build_key"]

    # other settings make another key: built again (here refused by the patch), never the cached asset
    other = ObjectsConfig(**{**config.__dict__, "surface_points": 64})
    refused = prepare_objects(sources, tmp_path / "run_c", other, seed=0, workers=0)
    assert set(refused.loc[refused["object_id"].isin(["user-box", "user-ball"]), "status"]) == {"rejected"}


def test_split_is_seeded_exact_and_respects_always_heldout():
    sources = [MeshSource(f"obj-{i:02d}", "user", "x.obj", always_heldout=i == 0) for i in range(21)]
    first = heldout_ids(sources, 0.25, seed=3)
    assert first == heldout_ids(sources, 0.25, seed=3)
    assert first != heldout_ids(sources, 0.25, seed=4)
    assert "obj-00" in first and len(first) == 1 + round(0.25 * 20)
    catalog = pd.DataFrame({"object_id": [s.object_id for s in sources], "status": ["ok"] * 20 + ["rejected"]})
    split = assign_split(catalog, first)
    assert set(split.loc[split["split"] == "heldout", "object_id"]) == first - {"obj-20"}
    assert split.loc[split["object_id"] == "obj-20", "split"].item() == ""


def test_heldout_objects_are_turned_about_z_by_their_seeded_yaw(tmp_path):
    """A held-out object is prepared turned about z by its own seeded angle; its catalog row and meta.json say by how much,
    and its shape is the unturned asset's turned (the table under it unchanged)."""
    path = tmp_path / "box.obj"
    trimesh.creation.box((0.08, 0.04, 0.12)).export(path)
    plain = MeshSource("user-box", "user", str(path))
    turned = turned_heldout([plain], {"user-box"}, seed=5)[0]
    assert turned.turn_deg == heldout_turn_deg("user-box", 5) != heldout_turn_deg("user-box", 6)
    assert 0 <= turned.turn_deg < 360 and turned_heldout([plain], set(), seed=5)[0].turn_deg == 0
    rows = [prepare_object(source, str(tmp_path / name), TINY.build_settings(0)) for source, name in ((plain, "plain"), (turned, "turned"))]
    assert rows[0]["turn_deg"] == 0 and rows[1]["turn_deg"] == pytest.approx(turned.turn_deg)
    meta = json.loads((tmp_path / "turned" / "assets" / "user-box" / "meta.json").read_text())
    assert meta["turned_about_z_deg"] == pytest.approx(turned.turn_deg)
    angle = np.radians(turned.turn_deg)
    rz = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    points = [load_asset([str(tmp_path / name)], "user-box").surface_points for name in ("plain", "turned")]
    # the turned asset's surface is the plain one's turned: every turned point lies on the turned plain box
    half = np.array([0.08, 0.04, 0.12]) / 2 / np.linalg.norm([0.04, 0.02, 0.06]) / 1.03
    back = points[1] @ rz  # turned back
    assert np.abs(back).max(axis=0) == pytest.approx(half, abs=1e-4)
    assert points[0][:, 2].min() == pytest.approx(points[1][:, 2].min(), abs=1e-4)


def test_cli_stops_at_once_on_a_missing_folder(tmp_path, capsys):
    from dexlite_pipeline.cli import main

    cfg = json.dumps({"seed": 0, "objects": {"builtin_count": 0, "mesh_dirs": [str(tmp_path / "gone")], "heldout_mesh_dirs": []}})
    assert main(["prepare-objects", "--config-json", cfg, "--catalog", str(tmp_path / "out" / "catalog.parquet"), "--record", str(tmp_path / "out" / "prepare_config.json")]) == 2
    assert "gone" in capsys.readouterr().err
    assert not (tmp_path / "out" / "catalog.parquet").exists()


def test_cli_fails_when_no_object_could_be_prepared(tmp_path, capsys, caplog):
    from dexlite_pipeline.cli import main

    meshes = tmp_path / "meshes"
    meshes.mkdir()
    for name, text in (BAD_MESHES["empty mesh"], BAD_MESHES["degenerate: flat"], BAD_MESHES["unreadable"]):
        (meshes / name).write_text(text)
    objects = {**TINY.__dict__, "mesh_dirs": [str(meshes)]}
    cfg = json.dumps({"seed": 0, "objects": objects})
    assert main(["prepare-objects", "--config-json", cfg, "--catalog", str(tmp_path / "out" / "catalog.parquet"), "--record", str(tmp_path / "out" / "prepare_config.json"), "--threads", "1"]) == 1
    assert "prepared 0/3 objects" in capsys.readouterr().out
    assert "none of the 3 objects could be prepared" in caplog.text


def test_the_builder_version_covers_the_code_that_builds_an_asset_and_not_the_choice_of_objects():
    """The asset cache's key hashes the building code: the mesh steps, CoACD and the grids, never the object sources, the
    household generators (a generated mesh's bytes are in the key already) or the other keys of config section objects."""
    from dexlite_pipeline.codehash import module_closure

    covered = {name.removeprefix("dexlite_pipeline.") for name in module_closure("dexlite_pipeline.objects.asset_building")}
    assert {"objects.asset_building", "objects.build", "objects.fidelity", "objects.solidify", "objects.asset_settings"} <= covered
    assert not covered & {"objects.config", "objects.sources", "objects.household", "objects.prepare", "stages.prepare_objects"}
