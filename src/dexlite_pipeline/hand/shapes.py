"""Collision geoms of a hand's MJCF as shapes: their kind and size, surface samples with normals, a box fitted to a mesh.

Everything here is in the geom's own frame (MuJoCo's convention: capsules and cylinders along
z, boxes by half extents, meshes as MuJoCo compiled them, i.e. re-centred and aligned with the
mesh's inertia axes) and in metres. Surface samples are deterministic and about ``spacing`` apart,
so their number follows the shape's area: dense enough for a penetration measure that counts
samples inside an object, and for choosing contact candidates among them by their normals.
"""

from __future__ import annotations

import math

import numpy as np

GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))
# MuJoCo geom type -> our name; the types a hand's collision geoms may have.
KINDS = {2: "sphere", 3: "capsule", 4: "ellipsoid", 5: "cylinder", 6: "box", 7: "mesh"}


def _count(area: float, spacing: float, least: int = 4) -> int:
    return max(least, int(math.ceil(area / spacing**2)))


def _fibonacci_sphere(count: int) -> np.ndarray:
    """``count`` unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    k = np.arange(count)
    z = 1.0 - 2.0 * (k + 0.5) / count
    rho = np.sqrt(1.0 - z**2)
    return np.stack([rho * np.cos(k * GOLDEN_ANGLE), rho * np.sin(k * GOLDEN_ANGLE), z], axis=1)


def _cylinder_side(radius: float, half: float, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    around = max(6, int(math.ceil(2 * math.pi * radius / spacing)))
    along = max(2, int(math.ceil(2 * half / spacing)) + 1)
    theta = np.arange(around) * 2 * math.pi / around
    z = np.linspace(-half, half, along)
    tt, zz = np.meshgrid(theta, z, indexing="ij")
    normals = np.stack([np.cos(tt), np.sin(tt), np.zeros_like(tt)], axis=-1).reshape(-1, 3)
    points = normals * radius
    points[:, 2] = zz.ravel()
    return points, normals


def _disc(radius: float, z: float, sign: float, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    count = _count(math.pi * radius**2, spacing, least=1)
    k = np.arange(count)
    r = radius * np.sqrt((k + 0.5) / count)
    points = np.stack([r * np.cos(k * GOLDEN_ANGLE), r * np.sin(k * GOLDEN_ANGLE), np.full(count, z)], axis=1)
    return points, np.tile([0.0, 0.0, sign], (count, 1))


def _box(half: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    points, normals = [], []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        nu, nv = (max(2, int(math.ceil(2 * half[a] / spacing)) + 1) for a in (u, v))
        gu, gv = np.meshgrid(np.linspace(-half[u], half[u], nu), np.linspace(-half[v], half[v], nv), indexing="ij")
        for sign in (-1.0, 1.0):
            face = np.zeros((gu.size, 3))
            face[:, axis], face[:, u], face[:, v] = sign * half[axis], gu.ravel(), gv.ravel()
            normal = np.zeros((gu.size, 3))
            normal[:, axis] = sign
            points.append(face)
            normals.append(normal)
    return np.concatenate(points), np.concatenate(normals)


def mesh_surface_samples(vertices: np.ndarray, faces: np.ndarray, spacing: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Points (P, 3) on a triangle mesh, area-weighted (a seeded draw), with their faces' unit normals (P, 3).

    The normals follow the faces' winding (MuJoCo meshes wind counter-clockwise seen from outside).
    """
    tri = vertices[faces]  # (F, 3, 3)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    keep = area > 0
    tri, cross, area = tri[keep], cross[keep], area[keep]
    count = _count(float(area.sum()), spacing)
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(tri), size=count, p=area / area.sum())
    a, b = rng.random(count), rng.random(count)
    flip = a + b > 1
    a[flip], b[flip] = 1 - a[flip], 1 - b[flip]
    chosen = tri[pick]
    points = chosen[:, 0] + a[:, None] * (chosen[:, 1] - chosen[:, 0]) + b[:, None] * (chosen[:, 2] - chosen[:, 0])
    normals = cross[pick] / np.linalg.norm(cross[pick], axis=1, keepdims=True)
    return points, normals


def fitted_box(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centre (3,) and half extents (3,) of a mesh's bounding box in the geom frame (m).

    The geom frame of a compiled mesh is aligned with its inertia axes, so this box hugs the
    mesh about as tightly as an oriented bounding box: the primitive the energies can use for
    a mesh geom, beside its surface samples.
    """
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    return (low + high) / 2, (high - low) / 2


def surface_samples(kind: str, size: np.ndarray, spacing: float, mesh: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Points (P, 3) on the surface of a geom, in its frame, with outward unit normals (P, 3).

    kind: a value of ``KINDS``; size: MuJoCo's ``geom_size`` (m); mesh: (vertices, faces) for a mesh geom.
    """
    size = np.asarray(size, dtype=np.float64)
    if kind == "sphere":
        normals = _fibonacci_sphere(_count(4 * math.pi * size[0] ** 2, spacing, least=8))
        return normals * size[0], normals
    if kind == "ellipsoid":  # a sphere stretched; normals of the implicit surface x²/a² + ... = 1
        unit = _fibonacci_sphere(_count(4 * math.pi * float(np.mean(size)) ** 2, spacing, least=8))
        normals = unit / size
        return unit * size, normals / np.linalg.norm(normals, axis=1, keepdims=True)
    if kind == "capsule":
        radius, half = size[0], size[1]
        side = _cylinder_side(radius, half, spacing)
        cap = _fibonacci_sphere(_count(4 * math.pi * radius**2, spacing, least=8))
        cap_points = cap * radius
        cap_points[:, 2] += np.where(cap[:, 2] >= 0, half, -half)
        return np.concatenate([side[0], cap_points]), np.concatenate([side[1], cap])
    if kind == "cylinder":
        radius, half = size[0], size[1]
        parts = [_cylinder_side(radius, half, spacing), _disc(radius, half, 1.0, spacing), _disc(radius, -half, -1.0, spacing)]
        return np.concatenate([p for p, _ in parts]), np.concatenate([n for _, n in parts])
    if kind == "box":
        return _box(size, spacing)
    if kind == "mesh":
        if mesh is None:
            raise ValueError("a mesh geom needs its vertices and faces")
        return mesh_surface_samples(mesh[0], mesh[1], spacing)
    raise ValueError(f"unsupported collision geom type {kind!r}")


def signed_distance(kind: str, size: np.ndarray, points: np.ndarray, box: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Signed distance (m, positive outside) of points (P, 3) in a geom's frame to the geom.

    Exact for spheres, capsules, cylinders and boxes; an ellipsoid is measured as its scaled
    sphere (right in sign, approximate in size); a mesh by its fitted box (``box``).
    """
    p = np.asarray(points, dtype=np.float64)
    size = np.asarray(size, dtype=np.float64)
    if kind == "sphere":
        return np.linalg.norm(p, axis=1) - size[0]
    if kind == "ellipsoid":
        return (np.linalg.norm(p / size, axis=1) - 1.0) * float(size.min())
    if kind == "capsule":
        z = np.clip(p[:, 2], -size[1], size[1])
        return np.linalg.norm(p - np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=1), axis=1) - size[0]
    if kind == "cylinder":
        d = np.stack([np.linalg.norm(p[:, :2], axis=1) - size[0], np.abs(p[:, 2]) - size[1]], axis=1)
        return np.minimum(d.max(axis=1), 0) + np.linalg.norm(np.maximum(d, 0), axis=1)
    if kind in ("box", "mesh"):
        centre, half = (np.zeros(3), size) if kind == "box" else box
        q = np.abs(p - centre) - half
        return np.minimum(q.max(axis=1), 0) + np.linalg.norm(np.maximum(q, 0), axis=1)
    raise ValueError(f"unsupported collision geom type {kind!r}")


__all__ = ["KINDS", "fitted_box", "mesh_surface_samples", "signed_distance", "surface_samples"]
