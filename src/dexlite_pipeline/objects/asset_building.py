"""Build one object's asset from its mesh file: load, check, make one closed solid, normalize, write.

``load_source_mesh`` -> ``check_shape`` -> ``prepared_solid`` (one closed solid, checked to be the input's shape:
``objects.solidify``, ``objects.fidelity``) -> ``normalize_mesh`` -> ``objects.build.write_asset``
(``build_asset``). A mesh that cannot be used raises ``MeshRejected`` with a one-line reason.

This module's code hash (with everything it imports) is the builder version in the key of a reusable asset
(``objects.prepare.builder_version``), so it imports nothing about choosing objects or about other config keys:
``source`` arguments are ``objects.sources.MeshSource`` records, read by attribute.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from dexlite_pipeline.objects.asset_settings import AssetBuildSettings
from dexlite_pipeline.objects.build import write_asset

# DexGraspNet's normalization: the max vertex radius becomes 1 / 1.03.
RADIUS_MARGIN = 1.03
MIN_FACES = 4
# Thinnest / largest bounding-box extent below this: a flat sheet, not a solid.
MIN_EXTENT_RATIO = 1e-3
# Volume of the normalized mesh (unit ball: 4.19) below this: no solid to grasp.
MIN_NORMALIZED_VOLUME = 1e-4

class MeshRejected(Exception):
    """A mesh that cannot become an object; the message is the catalog's one-line reason.

    ``deviation`` (``fidelity.ShapeDeviation``) when the refusal is that the prepared solid was not the input.
    """

    def __init__(self, reason: str, deviation=None):
        super().__init__(reason)
        self.deviation = deviation


def _as_trimesh(loaded):
    import trimesh

    if isinstance(loaded, trimesh.Trimesh):
        return loaded
    return trimesh.Trimesh()


def load_source_mesh(source):
    """Read the mesh file and apply the source's placement (URDF scale, then rotation, then its turn about z)."""
    import trimesh

    path = Path(source.file)
    try:
        mesh = _as_trimesh(trimesh.load(path, force="mesh", process=False))
        vertices = np.asarray(mesh.vertices, dtype=np.float64)
        faces = np.asarray(mesh.faces, dtype=np.int64)
    except Exception as exc:  # noqa: BLE001 - any parser failure is "unreadable"
        raise MeshRejected(f"unreadable: {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}".rstrip(": ")) from None
    if len(faces) == 0:
        if len(vertices) == 0 and path.stat().st_size > 0:
            raise MeshRejected(f"unreadable: no mesh data could be parsed from {path.name}")
        raise MeshRejected("empty mesh: no faces")
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        raise MeshRejected(f"non-finite vertices: {int(bad.sum())} of {len(vertices)} have NaN/inf coordinates")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise MeshRejected("unreadable: face indices out of range")
    vertices = vertices * np.asarray(source.scale_xyz)
    rotation = trimesh.transformations.euler_matrix(*source.rotation_rpy, axes="sxyz")[:3, :3]
    rotation = trimesh.transformations.rotation_matrix(np.radians(source.turn_deg), [0, 0, 1])[:3, :3] @ rotation
    return trimesh.Trimesh(vertices @ rotation.T, faces, process=False)


def prepared_solid(raw, metres_per_unit: float | None = None):
    """The one closed solid a placed mesh stands for, how it was made and how far it is from the input.

    ``objects.solidify`` makes it (one shell repaired; several bodies united, or remeshed;
    floating fragments set aside; a file holding several objects refused) and ``objects.fidelity``
    checks it is the input's shape. Returns (mesh, ``SolidRecord``, ``ShapeDeviation``); raises
    ``MeshRejected`` with the reason otherwise.
    """
    from dexlite_pipeline.objects.fidelity import NotTheInput, faithful_solid
    from dexlite_pipeline.objects.solidify import SeveralObjects

    try:
        mesh, record, deviation = faithful_solid(raw, metres_per_unit)
    except SeveralObjects as exc:
        raise MeshRejected(str(exc)) from None
    except NotTheInput as exc:
        raise MeshRejected(str(exc), exc.deviation) from None
    check_mesh(mesh)
    return mesh, record, deviation


def check_shape(mesh) -> None:
    """Reject a mesh that cannot bound a solid: flat (all on a plane or line) or under 4 real faces."""
    extents = np.asarray(mesh.extents, dtype=np.float64)
    if extents.max() <= 0 or extents.min() / extents.max() < MIN_EXTENT_RATIO:
        raise MeshRejected(f"degenerate: flat (extents {np.array2string(extents, precision=4)})")
    n_faces = int(mesh.nondegenerate_faces().sum())
    if n_faces < MIN_FACES:
        raise MeshRejected(f"degenerate: only {n_faces} non-degenerate faces")


def check_mesh(mesh) -> None:
    """Reject a repaired mesh that is not a usable solid."""
    check_shape(mesh)
    if not mesh.is_watertight:
        _, uses = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
        raise MeshRejected(
            f"not watertight after repair: {int((uses == 1).sum())} boundary edges, {int((uses > 2).sum())} non-manifold edges"
        )
    if not mesh.is_winding_consistent:
        raise MeshRejected("not watertight after repair: inconsistent face winding")


def normalize_mesh(mesh):
    """Centre on the bounding box and scale the max vertex radius to 1/1.03 (DexGraspNet).

    Returns (normalized mesh, centre in the source frame, scale factor applied).
    """
    centre = (mesh.bounds[0] + mesh.bounds[1]) / 2
    radius = float(np.linalg.norm(mesh.vertices - centre, axis=1).max())
    factor = 1.0 / (radius * RADIUS_MARGIN)
    normalized = mesh.copy()
    normalized.apply_translation(-centre)
    normalized.apply_scale(factor)
    return normalized, centre, factor


def build_asset(source, objects_dir: Path, settings: AssetBuildSettings, key: str, file_label: str):
    """Build and write ``source``'s asset in ``objects_dir``; returns (``write_asset``'s summary, the solid's
    ``SolidRecord``, its ``ShapeDeviation``). ``key``: the reuse key recorded in meta.json; ``file_label``: the file
    as the catalog shows it. Raises ``MeshRejected`` with the reason when the mesh cannot become an object."""
    raw = load_source_mesh(source)
    check_shape(raw)  # before repair, which could close a few stray triangles into a "solid"
    mesh, made, deviation = prepared_solid(raw, source.metres_per_unit)
    mesh, centre, factor = normalize_mesh(mesh)
    if mesh.volume < MIN_NORMALIZED_VOLUME:
        raise MeshRejected(f"degenerate: zero volume ({mesh.volume:.2e} after normalization)")
    meta = {
        "source": source.source,
        "file": file_label,
        "placement_scale_xyz": list(source.scale_xyz),
        "placement_rotation_rpy": list(source.rotation_rpy),
        "turned_about_z_deg": float(source.turn_deg),  # after the placement: a held-out object's seeded yaw
        "normalization_centre": centre.tolist(),
        "normalization_factor": factor,
        # Real radius (m) when the file's units are known to be metres (generated objects), else None.
        "real_radius_m": _real_radius_m(source, raw, factor),
        "center_mass": np.asarray(mesh.center_mass).tolist(),
        "build_key": key,
        # how the file became one solid and how far that solid is from the file's surface (fractions of its size)
        "preparation": dataclasses.asdict(made) | {"summary": made.summary()},
        "deviation": deviation.as_record() | {"summary": deviation.summary()},
    }
    if source.recorded_rest is not None:  # trained on only: no collision pieces, the dataset's resting pose (objects.dataset_collision)
        meta["recorded_rest_pose"] = source.recorded_rest.as_dict()
        return write_asset(mesh, source.object_id, objects_dir, settings, meta, convex_pieces=[]), made, deviation
    return write_asset(mesh, source.object_id, objects_dir, settings, meta), made, deviation


def _radius_about_box_centre(vertices: np.ndarray) -> float:
    return float(np.linalg.norm(vertices - (vertices.min(axis=0) + vertices.max(axis=0)) / 2, axis=1).max())


def _real_radius_m(source, placed, factor: float) -> float | None:
    """The prepared object's real radius (m: largest vertex distance from its bounding-box centre), or None when unknown.

    A source's ``real_radius_m`` is its mesh as placed, unturned; a turn about z moves the bounding box's centre, so a turned
    object's radius is that value times the prepared radius (1 / (``factor`` x 1.03)) over the unturned one of the same
    placed mesh."""
    if source.real_radius_m is None or not source.turn_deg:
        return source.real_radius_m
    vertices = np.asarray(placed.vertices, dtype=np.float64)
    angle = np.radians(source.turn_deg)
    unturn = np.array([[np.cos(angle), np.sin(angle), 0.0], [-np.sin(angle), np.cos(angle), 0.0], [0.0, 0.0, 1.0]])
    return source.real_radius_m / (factor * RADIUS_MARGIN) / _radius_about_box_centre(vertices @ unturn.T)
