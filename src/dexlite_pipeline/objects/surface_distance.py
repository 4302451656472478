"""Signed distance that is exact near the object's surface: the SDF grid, refined by the mesh.

``SurfaceDistance`` answers like ``SdfBank.signed_distance`` (metres, positive inside,
differentiable in the points) but replaces the grid's trilinear value by the exact distance to
the mesh (``objects.mesh_distance``) wherever a point may lie within ``band_m`` of the
surface or inside it. Trilinear interpolation of an exact SDF errs by at most √3/2 of a
voxel (``SdfBank`` nodes hold exact distances), so a grid value below −(band + that bound)
proves a point is farther than the band outside, and only the other points are looked up.

The exact value is written −n·(x − c) with the nearest mesh point c and the outward unit
direction n held fixed: its value is the distance and its gradient −n is the distance's
exact gradient, so optimizers can use it as they use the grid.
"""

from __future__ import annotations

import numpy as np
import torch

from dexlite_pipeline.objects.assets import SdfBank
from dexlite_pipeline.objects.mesh_distance import MeshDistance

SQRT3_HALF = 3**0.5 / 2
SEQUENCE_CHUNK = 1024  # points per independently seeded chunk of ``surface_point_sequence``
SHARP_EDGE_ANGLE_RAD = 0.5  # an edge whose faces' normals differ by more (~29°) is a crease (``sharp_edge_points``)
MAX_EDGE_POINTS = 50_000


class SurfaceDistance:
    """The grid of ``bank`` plus each object's mesh (in the bank's order), for exact distances near the surface."""

    def __init__(self, bank: SdfBank, meshes: list[MeshDistance]) -> None:
        if len(meshes) != len(bank.object_ids):
            raise ValueError(f"SurfaceDistance needs one mesh per bank object ({len(bank.object_ids)}), got {len(meshes)}")
        self.bank = bank
        self.meshes = meshes
        self.grid_error = bank.voxel_size * SQRT3_HALF  # (n_objects,) normalized units: the interpolation bound

    @classmethod
    def from_meshes(cls, bank: SdfBank, meshes) -> "SurfaceDistance":
        """From the bank's objects' normalized meshes (trimesh.Trimesh, in the bank's order)."""
        return cls(bank, [MeshDistance.from_mesh(np.asarray(m.vertices), np.asarray(m.faces)) for m in meshes])

    def signed_distance(self, points_m: torch.Tensor, object_index: torch.Tensor, scale: torch.Tensor, band_m: torch.Tensor | float = 0.0) -> torch.Tensor:
        """Distance (metres, positive inside) at ``points_m`` (..., 3), exact wherever it exceeds −``band_m``.

        ``object_index`` and ``scale`` broadcast to the points' batch shape as in
        ``SdfBank.signed_distance``; ``band_m`` is a float or a tensor broadcasting to it.
        """
        shape = points_m.shape[:-1]
        object_index = object_index.reshape(object_index.shape + (1,) * (len(shape) - object_index.dim())).expand(shape)
        scale = scale.to(points_m.dtype).reshape(scale.shape + (1,) * (len(shape) - scale.dim())).expand(shape)
        grid, _ = self.bank.signed_distance(points_m, object_index, scale, with_normal=False)
        with torch.no_grad():
            band = torch.as_tensor(band_m, dtype=grid.dtype, device=grid.device)
            near = grid > -(band + self.grid_error[object_index] * scale)
        if not bool(near.any()):
            return grid
        flat_points = points_m.reshape(-1, 3)
        flat_near = near.reshape(-1).nonzero().squeeze(1)
        flat_object = object_index.reshape(-1).index_select(0, flat_near)
        flat_scale = scale.reshape(-1).index_select(0, flat_near)
        nearest = torch.empty(len(flat_near), 3, dtype=points_m.dtype, device=points_m.device)
        direction = torch.empty_like(nearest)
        for obj in torch.unique(flat_object).tolist():
            rows = (flat_object == obj).nonzero().squeeze(1)
            s = flat_scale.index_select(0, rows)
            local = (flat_points.index_select(0, flat_near.index_select(0, rows)).detach() / s[:, None]).cpu().double().numpy()
            _, c, n = self.meshes[obj].query(local)
            nearest[rows] = torch.as_tensor(c, dtype=points_m.dtype, device=points_m.device) * s[:, None]
            direction[rows] = torch.as_tensor(n, dtype=points_m.dtype, device=points_m.device)
        exact = -(direction * (flat_points.index_select(0, flat_near) - nearest)).sum(-1)
        return grid.reshape(-1).index_put((flat_near,), exact).reshape(shape)


def surface_point_sequence(mesh, count: int, seed: int = 0) -> np.ndarray:
    """(count, 3) points uniformly distributed over the area of ``mesh`` (trimesh.Trimesh), deterministic for a seed.

    Drawn in chunks of ``SEQUENCE_CHUNK`` points, each from its own random stream, so the
    first n points are the same whatever ``count`` ≥ n is asked for, and every prefix is
    itself uniform over the surface: a grasp at scale s uses the first ``area·s²/spacing²``
    points whatever length was drawn for other scales.
    """
    corners = np.asarray(mesh.vertices, np.float64)[np.asarray(mesh.faces)]
    area = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1) / 2
    cumulative = np.cumsum(area)
    chunks = []
    for chunk in range(-(-int(count) // SEQUENCE_CHUNK)):
        rng = np.random.default_rng([seed, chunk])
        face = np.minimum(np.searchsorted(cumulative, rng.random(SEQUENCE_CHUNK) * cumulative[-1], side="right"), len(area) - 1)
        r1, r2 = rng.random(SEQUENCE_CHUNK), rng.random(SEQUENCE_CHUNK)
        root = np.sqrt(r1)
        a, b, c = corners[face, 0], corners[face, 1], corners[face, 2]
        chunks.append((1 - root)[:, None] * a + (root * (1 - r2))[:, None] * b + (root * r2)[:, None] * c)
    points = np.concatenate(chunks) if chunks else np.zeros((0, 3))
    return points[: int(count)].astype(np.float32)


def sharp_edge_points(mesh, spacing: float, min_angle_rad: float = SHARP_EDGE_ANGLE_RAD, max_points: int = MAX_EDGE_POINTS) -> np.ndarray:
    """(K, 3) points along the mesh's sharp edges, ``spacing`` apart (normalized units), ends included.

    An edge is sharp where its two faces' normals differ by more than ``min_angle_rad``: there the
    surface has a crease that points spread over the area reach only within about their spacing,
    while an edge cutting into a finger is the part of the object deepest in it. At most
    ``max_points`` (the spacing grows beyond that).
    """
    if len(mesh.faces) == 0:
        return np.zeros((0, 3), np.float32)
    sharp = np.asarray(mesh.face_adjacency_angles) > min_angle_rad
    ends = np.asarray(mesh.vertices, np.float64)[np.asarray(mesh.face_adjacency_edges)[sharp]]  # (E, 2, 3)
    if len(ends) == 0:
        return np.zeros((0, 3), np.float32)
    length = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
    spacing = max(spacing, float(length.sum()) / max_points)
    steps = np.maximum(1, np.ceil(length / spacing).astype(np.int64))
    edge = np.repeat(np.arange(len(ends)), steps + 1)
    t = np.concatenate([np.linspace(0.0, 1.0, k + 1) for k in steps])
    return (ends[edge, 0] + t[:, None] * (ends[edge, 1] - ends[edge, 0])).astype(np.float32)
