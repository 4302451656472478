"""SDF grid accuracy against trimesh's exact signed distance, and gradients through SdfBank."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh

from dexlite_pipeline.objects.assets import SdfBank, load_asset
from dexlite_pipeline.objects.build import signed_distance_grid, write_asset
from dexlite_pipeline.objects.config import AssetBuildSettings
from dexlite_pipeline.objects.config import ObjectsConfig
from dexlite_pipeline.objects.asset_building import normalize_mesh

SCALE = 0.1
BAND_M = 0.02


def _pipeline_settings() -> AssetBuildSettings:
    """The default config's grid (resolution, padding, exact band), with few surface samples."""
    defaults = ObjectsConfig().build_settings(seed=0)
    return AssetBuildSettings(**{**defaults.__dict__, "surface_points": 256})


def _near_surface_points(mesh, count: int, seed: int) -> np.ndarray:
    """Points within 2 cm (at scale 0.1) of the surface, inside and outside, normalized units."""
    rng = np.random.default_rng(seed)
    points, faces = trimesh.sample.sample_surface(mesh, count, seed=seed)
    offsets = rng.uniform(-BAND_M / SCALE, BAND_M / SCALE, size=(count, 1))
    directions = mesh.face_normals[faces] + rng.normal(scale=0.3, size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    candidates = points + offsets * directions
    exact = trimesh.proximity.signed_distance(mesh, candidates)  # positive inside
    keep = np.abs(exact) <= BAND_M / SCALE
    return candidates[keep], exact[keep]


@pytest.fixture(scope="module")
def shapes(tmp_path_factory):
    root = tmp_path_factory.mktemp("sdf_objects")
    meshes = {
        "box": normalize_mesh(trimesh.creation.box((1.0, 0.7, 0.4)))[0],
        "torus": normalize_mesh(trimesh.creation.torus(1.0, 0.35, major_sections=48, minor_sections=24))[0],
    }
    for object_id, mesh in meshes.items():
        write_asset(mesh, object_id, root, _pipeline_settings(), {"source": "test"}, convex_pieces=[mesh])
    return root, meshes


@pytest.mark.parametrize("object_id", ["box", "torus"])
def test_grid_matches_exact_signed_distance_within_2cm(shapes, object_id):
    root, meshes = shapes
    points, exact = _near_surface_points(meshes[object_id], 3000, seed=1)
    bank = SdfBank([load_asset(root, object_id)])
    points_m = torch.as_tensor(points * SCALE, dtype=torch.float32)[None]
    distance_m, _ = bank.signed_distance(points_m, torch.zeros(1, dtype=torch.long), torch.full((1,), SCALE))
    error_mm = np.abs(distance_m[0].numpy() - exact * SCALE) * 1000
    assert len(points) > 2000
    assert np.median(error_mm) <= 0.3, np.median(error_mm)
    assert error_mm.max() <= 1.0, error_mm.max()
    print(f"{object_id}: median {np.median(error_mm):.3f} mm, max {error_mm.max():.3f} mm over {len(points)} points")


def test_gradients_flow_and_point_inward(shapes):
    root, meshes = shapes
    bank = SdfBank([load_asset(root, "box"), load_asset(root, "torus")])
    mesh = meshes["torus"]
    surface, faces = trimesh.sample.sample_surface(mesh, 500, seed=2)
    outward = mesh.face_normals[faces]
    points_m = torch.as_tensor((surface + 0.05 * outward) * SCALE, dtype=torch.float32)[None].requires_grad_(True)
    distance_m, normal = bank.signed_distance(points_m, torch.ones(1, dtype=torch.long), torch.full((1,), SCALE))
    distance_m.sum().backward()
    grad = points_m.grad[0].numpy()
    assert np.isfinite(grad).all()
    # d is positive inside: its gradient points inward, against the outward normal.
    cosine = -(grad * outward).sum(1) / np.linalg.norm(grad, axis=1)
    assert np.median(cosine) > 0.95
    assert np.median((normal[0].detach().numpy() * outward).sum(1)) > 0.95


def test_narrow_band_equals_exact_grid_near_surface_with_correct_sign():
    mesh = normalize_mesh(trimesh.creation.torus(1.0, 0.35, major_sections=24, minor_sections=12))[0]
    exact, grid_min, voxel = signed_distance_grid(mesh, 48, 0.25)
    banded, grid_min_b, voxel_b = signed_distance_grid(mesh, 48, 0.25, exact_band=0.2)
    np.testing.assert_array_equal(grid_min, grid_min_b)
    near = np.abs(exact) < 0.2
    np.testing.assert_array_equal(banded[near], exact[near])
    assert (np.sign(banded) == np.sign(exact)).all()
    coarse_voxel = voxel * 47 / (47 // 4)  # the coarse grid spans the same box with 4x fewer cells
    assert np.abs(banded - exact).max() <= coarse_voxel * np.sqrt(3)


def test_watertight_mesh_distances_equal_the_winding_number_signed_ones():
    """The pseudonormal sign used for closed meshes gives the generalized winding number's distances; an open mesh
    keeps igl's default, the winding number (a pseudonormal sign is undefined across a hole)."""
    import igl

    from dexlite_pipeline.objects.build import _grid_points, _igl_signed_distance

    mesh = normalize_mesh(trimesh.creation.torus(1.0, 0.35, major_sections=24, minor_sections=12))[0]
    points = _grid_points(np.full(3, -1.3), 2.6 / 23, 24)
    vertices, faces = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    winding = -igl.signed_distance(points, vertices, faces, igl.SIGNED_DISTANCE_TYPE_WINDING_NUMBER)[0]
    assert mesh.is_watertight
    np.testing.assert_allclose(_igl_signed_distance(points, mesh), winding, atol=1e-12)
    assert (winding > 0).any() and (winding < 0).any()
    opened = trimesh.Trimesh(mesh.vertices, mesh.faces[10:], process=False)
    assert not opened.is_watertight
    default = -igl.signed_distance(points, vertices, np.asarray(opened.faces, np.int64), igl.SIGNED_DISTANCE_TYPE_DEFAULT)[0]
    np.testing.assert_allclose(_igl_signed_distance(points, opened), default, atol=1e-12)
