"""Meshes in the forms people have them: each is prepared as its intended solid, or refused with a reason; none changes shape."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from dexlite_pipeline.objects import mesh_forms
from dexlite_pipeline.objects.config import ObjectsConfig
from dexlite_pipeline.objects.fidelity import MAX_BOUNDS_ERROR, MAX_SURFACE_P99, NotTheInput, faithful_solid, shape_deviation
from dexlite_pipeline.objects.prepare import prepare_object
from dexlite_pipeline.objects.sources import MeshSource

TINY = ObjectsConfig(
    builtin_count=0, benchmark_objects=0, sdf_resolution=20, sdf_exact_band=0.2, surface_points=128,
    coacd_mcts_iterations=10, coacd_mcts_nodes=5, coacd_mcts_max_depth=1, coacd_resolution=300,
)  # fmt: skip
METRES_PER_UNIT = {"m": 1.0, "mm": 0.001}
SLOW = {"mug_convex_pieces", "can_convex_pieces", "open_bottom_scan"}  # CoACD or the volumetric remesh: ~10 s each
REFUSALS = {"two_objects_far_apart": "2 separate objects in one file", "near_flat_sheet": "degenerate: flat"}


def _prepared_in_file_frame(objects_dir, object_id) -> trimesh.Trimesh:
    """The prepared asset's mesh mapped back into the mesh file's coordinates (meta.json's normalization)."""
    folder = objects_dir / "assets" / object_id
    meta = json.loads((folder / "meta.json").read_text())
    mesh = trimesh.load(folder / "mesh.obj", force="mesh", process=False)
    return trimesh.Trimesh(np.asarray(mesh.vertices) / meta["normalization_factor"] + np.asarray(meta["normalization_centre"]),
                           mesh.faces, process=False)  # fmt: skip


@pytest.mark.parametrize(
    "name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW else n for n in mesh_forms.CORPUS]
)  # fmt: skip
def test_each_awkward_mesh_is_its_intended_solid_or_refused(tmp_path, name):
    builder, units = mesh_forms.CORPUS[name]
    given, intended = builder()
    path = tmp_path / f"{name}.obj"
    given.export(path)
    source = MeshSource(f"user-{name}", "user", str(path), metres_per_unit=METRES_PER_UNIT[units])
    row = prepare_object(source, str(tmp_path / "out"), TINY.build_settings(0))
    if intended is None:
        assert row["status"] == "rejected"
        assert row["reason"].startswith(REFUSALS[name]), row["reason"]
        assert "\n" not in row["reason"]
        return
    assert row["status"] == "ok", row["reason"]
    prepared = _prepared_in_file_frame(tmp_path / "out", source.object_id)
    truth = shape_deviation([intended], prepared, input_is_closed=True)
    assert truth.bounds_error <= MAX_BOUNDS_ERROR, truth.summary()
    assert truth.surface_p99 <= MAX_SURFACE_P99, truth.summary()
    # the catalog row and meta.json record the deviation from the file's own surface and how the solid was made
    assert 0 <= row["surface_deviation"] <= MAX_SURFACE_P99 and 0 <= row["bounds_deviation"] <= MAX_BOUNDS_ERROR
    meta = json.loads((tmp_path / "out" / "assets" / source.object_id / "meta.json").read_text())
    assert meta["deviation"]["bounds_error"] == pytest.approx(row["bounds_deviation"])
    assert meta["preparation"]["summary"] == row["preparation"]


def test_the_old_preparations_wrong_shapes_are_caught_by_the_check():
    """The shapes the earlier repair made of a three-shell bottle (its cap alone) and of a convex-piece can (one piece)."""
    bottle, _ = mesh_forms.three_shell_bottle()
    cap = bottle.split(only_watertight=False)[-1]
    assert shape_deviation([mesh_forms.one_shell_bottle()], cap, input_is_closed=True).problem() is not None
    can = mesh_forms.check_can()
    piece = mesh_forms.slab_sector_pieces(can, 4, 8)[0]
    deviation = shape_deviation([can], piece, input_is_closed=True)
    assert "input surface lost" in deviation.problem() or "bounding box" in deviation.problem()


def test_a_union_that_keeps_walls_inside_is_not_the_input():
    """Touching convex pieces whose union keeps the cut faces as internal walls: the check sees the walls."""
    pieces = mesh_forms.slab_sector_pieces(mesh_forms.check_can(), 2, 4)
    walls = trimesh.util.concatenate(pieces)  # every piece's cut faces still there, closed bodies touching
    deviation = shape_deviation(pieces, walls, input_is_closed=True)
    assert deviation.surface_p99_prepared_to_in > MAX_SURFACE_P99


def test_a_shape_that_no_route_makes_faithfully_is_refused_with_what_changed(monkeypatch):
    """With the remesh made useless (a grid of 4 cells), a can of touching pieces cannot be prepared: refused, not changed."""
    from dexlite_pipeline.objects import remesh, solidify

    monkeypatch.setattr(remesh, "REMESH_VOXELS", 4)
    monkeypatch.setattr(solidify, "union_of_closed_bodies", lambda bodies: trimesh.util.concatenate(bodies))
    given, _ = mesh_forms.can_as_convex_pieces()
    with pytest.raises(NotTheInput, match="prepared solid is not the input: .*32 bodies.*the volumetric remesh") as caught:
        faithful_solid(trimesh.Trimesh(given.vertices, given.faces, process=False))
    assert caught.value.deviation.surface_p99 > MAX_SURFACE_P99


@pytest.mark.slow
def test_touching_pieces_whose_union_keeps_walls_are_remeshed_into_the_solid():
    """The can's 32 pieces as computed (cut faces a rounding error apart): the union keeps walls, the remesh does not."""
    given, can = mesh_forms.can_as_convex_pieces()
    solid, record, deviation = faithful_solid(trimesh.Trimesh(given.vertices, given.faces, process=False))
    assert record.route == "volumetric remesh" and record.bodies_kept == 32
    assert any("union of closed bodies was not the input" in note for note in record.notes)
    assert solid.is_watertight and solid.body_count == 1
    truth = shape_deviation([can], solid, input_is_closed=True)
    assert truth.surface_p99 <= MAX_SURFACE_P99 and truth.bounds_error <= MAX_BOUNDS_ERROR, truth.summary()
    assert truth.volume_ratio == pytest.approx(1.0, abs=0.01)
