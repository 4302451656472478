"""Mesh repair of the kinds of damage real meshes have: open bottoms, holes that touch, split seams."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from dexlite_pipeline.objects.config import ObjectsConfig
from dexlite_pipeline.objects.asset_building import check_mesh, prepared_solid
from dexlite_pipeline.objects.prepare import prepare_object
from dexlite_pipeline.objects.sources import MeshSource

TINY = ObjectsConfig(
    builtin_count=0, sdf_resolution=20, surface_points=128,
    coacd_mcts_iterations=10, coacd_mcts_nodes=5, coacd_mcts_max_depth=1, coacd_resolution=300,
)  # fmt: skip


def open_bottom_box_with_touching_holes() -> tuple[trimesh.Trimesh, trimesh.Trimesh]:
    """An 8 cm box without its bottom and with two 2 x 2 cm holes in the top that meet at one corner."""
    box = trimesh.creation.box((0.08, 0.08, 0.08)).subdivide().subdivide().subdivide()  # 1 cm grid
    centre = box.triangles_center
    top = np.isclose(centre[:, 2], 0.04)
    first = top & (centre[:, 0] > -0.02) & (centre[:, 0] < 0) & (centre[:, 1] > -0.02) & (centre[:, 1] < 0)
    second = top & (centre[:, 0] > 0) & (centre[:, 0] < 0.02) & (centre[:, 1] > 0) & (centre[:, 1] < 0.02)
    bottom = np.isclose(centre[:, 2], -0.04)
    return box, trimesh.Trimesh(box.vertices, box.faces[~(first | second | bottom)], process=False)


def split_seam(mesh: trimesh.Trimesh, jitter_m: float, seed: int = 0) -> trimesh.Trimesh:
    """The mesh with the vertices of its x > 0, y = 0 seam duplicated (slightly moved) for the faces at y < 0."""
    vertices, faces = np.asarray(mesh.vertices), np.asarray(mesh.faces).copy()
    seam = np.flatnonzero(np.isclose(vertices[:, 1], 0.0) & (vertices[:, 0] > 0))
    copies = vertices[seam] + np.random.default_rng(seed).normal(0.0, jitter_m, (len(seam), 3))
    remap = np.arange(len(vertices))
    remap[seam] = len(vertices) + np.arange(len(seam))
    lower = mesh.triangles_center[:, 1] < 0
    faces[lower] = remap[faces[lower]]
    return trimesh.Trimesh(np.vstack([vertices, copies]), faces, process=False)


def open_bottom_cylinder() -> tuple[trimesh.Trimesh, trimesh.Trimesh]:
    cylinder = trimesh.creation.cylinder(radius=0.04, height=0.08, sections=32)
    bottom = cylinder.face_normals[:, 2] < -0.99
    return cylinder, trimesh.Trimesh(cylinder.vertices, cylinder.faces[~bottom], process=False)


def test_open_bottom_and_holes_meeting_at_a_corner_are_closed_keeping_the_volume():
    closed, damaged = open_bottom_box_with_touching_holes()
    assert not damaged.is_watertight
    repaired = prepared_solid(damaged)[0]
    check_mesh(repaired)
    assert repaired.is_watertight and repaired.is_winding_consistent
    assert repaired.volume == pytest.approx(closed.volume, rel=0.02)


def test_duplicated_seam_vertices_are_welded_and_the_open_bottom_closed():
    closed, cup = open_bottom_cylinder()
    damaged = split_seam(cup, jitter_m=1e-6)  # coordinates written with ~6 significant digits
    assert len(damaged.vertices) > len(closed.vertices)
    repaired = prepared_solid(damaged)[0]
    check_mesh(repaired)
    assert repaired.is_watertight
    assert repaired.volume == pytest.approx(closed.volume, rel=0.01)
    # The seam is joined, not patched over: no vertex beyond the closed shape's own.
    assert len(repaired.vertices) <= len(closed.vertices)


@pytest.mark.parametrize("suffix", [".obj", ".stl"])
def test_damaged_mesh_files_are_prepared(tmp_path, suffix):
    closed, cup = open_bottom_cylinder()
    path = tmp_path / f"cup{suffix}"
    split_seam(cup, jitter_m=1e-6).export(path)
    row = prepare_object(MeshSource("user-cup", "user", str(path)), str(tmp_path / "out"), TINY.build_settings(0))
    assert row["status"] == "ok", row["reason"]
    assert row["watertight"]
    assert (tmp_path / "out" / "assets" / "user-cup" / "mesh.obj").is_file()
