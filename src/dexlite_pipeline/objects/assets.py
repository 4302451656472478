"""Prepared object assets: the on-disk layout every stage reads, and a differentiable SDF.

One folder per object under ``<objects_dir>/assets/<object_id>/``:

- ``mesh.obj``        the normalized, watertight mesh (max vertex radius 1/1.03, DexGraspNet's
                      normalization; imported DexGraspNet meshes keep their own frame);
- ``convex/NNN.obj``  convex pieces (CoACD) in the same frame, for simulation;
- ``arrays.zarr``     ``sdf`` float32 (G, G, G), signed distance on a regular grid in
                      normalized units, *positive inside*, indexed [x, y, z]; attributes
                      ``grid_min`` (3,) and ``voxel_size``; ``surface_points`` (P, 3) and
                      ``surface_normals`` (P, 3, outward);
- ``meta.json``       id, source, file, normalization, volume, piece count.

A grasp carries a ``scale`` s: the object in metres is s times the normalized mesh, so
its signed distance is d_s(x) = s * d_1(x / s). One grid per object serves every scale.
``<objects_dir>/catalog.parquet`` lists every object (ok or rejected, with the reason).
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)
CATALOG_NAME = "catalog.parquet"
# The catalog's columns, in order: written by object preparation and by the DexGraspNet import.
# preparation: how the file became one solid; surface_deviation (two-sided p99 surface distance), bounds_deviation
# (largest bounding-box corner difference): prepared solid versus input, fractions of the input's largest extent;
# volume_ratio: prepared / input volume (NaN where the input is open) (objects.fidelity).
CATALOG_COLUMNS = ("object_id", "source", "file", "watertight", "volume", "n_convex_pieces", "status", "reason",
                   "preparation", "surface_deviation", "bounds_deviation", "volume_ratio", "turn_deg", "split")
ASSETS_DIR = "assets"


class ObjectAssetError(ValueError):
    """An object asset that is missing or malformed."""


@dataclass
class ObjectAsset:
    """One prepared object, in its normalized frame (multiply by ``scale`` for metres)."""

    object_id: str
    directory: Path
    sdf: np.ndarray  # (G, G, G) float32, positive inside
    grid_min: np.ndarray  # (3,)
    voxel_size: float
    surface_points: np.ndarray  # (P, 3)
    surface_normals: np.ndarray  # (P, 3)
    meta: dict

    @property
    def mesh_path(self) -> Path:
        return self.directory / "mesh.obj"

    @property
    def convex_paths(self) -> list[Path]:
        return sorted((self.directory / "convex").glob("*.obj"))

    @property
    def real_scale(self) -> float | None:
        """The scale at which the object has its real size: 1 / the normalization factor, for an object whose file is
        known to be in metres (generated household objects record ``real_radius_m``); None for any other."""
        factor = self.meta.get("normalization_factor")
        if self.meta.get("real_radius_m") is None or not isinstance(factor, (int, float)) or not factor > 0:
            return None
        return 1.0 / float(factor)

    def load_mesh(self):
        """The normalized mesh as a trimesh.Trimesh."""
        import trimesh

        return trimesh.load(self.mesh_path, force="mesh", process=False)


def asset_dir(objects_dir: str | os.PathLike, object_id: str) -> Path:
    return Path(objects_dir) / ASSETS_DIR / object_id


def find_asset_dir(objects_dirs, object_id: str) -> Path:
    """The asset folder of ``object_id`` in the first of ``objects_dirs`` (one or several) that has it."""
    dirs = [objects_dirs] if isinstance(objects_dirs, (str, os.PathLike)) else list(objects_dirs)
    for d in dirs:
        candidate = asset_dir(d, object_id)
        if (candidate / "arrays.zarr").exists():
            return candidate
    raise ObjectAssetError(f"object {object_id!r} has no prepared asset in {', '.join(str(d) for d in dirs)}")


def load_asset(objects_dirs, object_id: str) -> ObjectAsset:
    """Load one object's arrays and metadata from one objects dir or a list of them.

    Anything missing, unreadable or of the wrong shape is an ``ObjectAssetError`` naming
    the object and the path, so that callers can set that one object aside.
    """
    import zarr

    directory = find_asset_dir(objects_dirs, object_id)
    arrays_path = directory / "arrays.zarr"
    try:
        group = zarr.open_group(str(arrays_path), mode="r")
        sdf = np.asarray(group["sdf"][...], dtype=np.float32)
        grid_min = np.asarray(group.attrs["grid_min"], dtype=np.float32)
        voxel_size = float(group.attrs["voxel_size"])
        surface_points = np.asarray(group["surface_points"][...], dtype=np.float32)
        surface_normals = np.asarray(group["surface_normals"][...], dtype=np.float32)
    except (OSError, ValueError, KeyError, TypeError, RuntimeError) as exc:  # zarr and its codecs raise all of these
        raise ObjectAssetError(f"object {object_id!r}: cannot read {arrays_path}: {type(exc).__name__}: {exc}") from None
    cubic_grid = sdf.ndim == 3 and len(set(sdf.shape)) == 1 and grid_min.shape == (3,)
    if not cubic_grid or surface_points.shape[1:] != (3,) or surface_normals.shape != surface_points.shape:
        raise ObjectAssetError(
            f"object {object_id!r}: {arrays_path} has sdf {sdf.shape}, grid_min {grid_min.shape}, "
            f"surface_points {surface_points.shape}, surface_normals {surface_normals.shape}; "
            "expected a cubic grid, (3,) and two equal (P, 3)"
        )
    meta_path = directory / "meta.json"
    try:
        meta = json.loads(meta_path.read_text()) if meta_path.exists() else {}
    except (OSError, ValueError) as exc:
        raise ObjectAssetError(f"object {object_id!r}: cannot read {meta_path}: {exc}") from None
    return ObjectAsset(
        object_id=object_id,
        directory=directory,
        sdf=sdf,
        grid_min=grid_min,
        voxel_size=voxel_size,
        surface_points=surface_points,
        surface_normals=surface_normals,
        meta=meta,
    )


CATALOG_REQUIRED_COLUMNS = ("object_id", "status")  # what the stages that read a catalog use


def read_object_table(path: str | os.PathLike, name: str, required_columns: tuple[str, ...], made_by: str):
    """An object-level Parquet table (``name``: 'object catalog', 'stability table') that has ``required_columns``.

    Every stage reads these tables through here, so a bad one stops it with one line naming
    the file and the problem: FileNotFoundError if missing (``made_by`` says which stage
    writes it), ValueError if unreadable or lacking a column.
    """
    import pandas as pd

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: {name} not found (run {made_by} first)")
    try:
        table = pd.read_parquet(path)
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: cannot read the {name} ({exc})") from None
    missing = [c for c in required_columns if c not in table.columns]
    if missing:
        raise ValueError(f"{path}: {name} lacks column(s) {', '.join(missing)}")
    return table


def read_catalog(objects_dir: str | os.PathLike):
    """The object catalog of ``objects_dir`` as a pandas DataFrame, checked by ``read_object_table``."""
    return read_object_table(Path(objects_dir) / CATALOG_NAME, "object catalog", CATALOG_REQUIRED_COLUMNS, "prepare_objects")


def ok_object_ids(objects_dirs) -> set[str]:
    """Ids of the objects whose status is ok in the catalogs of one objects dir or several."""
    dirs = [objects_dirs] if isinstance(objects_dirs, (str, os.PathLike)) else list(objects_dirs)
    ids: set[str] = set()
    for d in dirs:
        catalog = read_catalog(d)
        ids |= set(catalog.loc[catalog["status"] == "ok", "object_id"].astype(str))
    return ids


def object_splits(objects_dirs, ok_only: bool = True) -> dict[str, str]:
    """Object id -> split (``train`` / ``heldout``) from the catalogs (the first catalog naming an object wins).

    ``ok_only``: only objects whose status is ok (what training and sampling may use); False
    also maps rejected objects (the evaluation reports every object it was asked about). A dir
    without a catalog, or a catalog without a split column, is logged and skipped: its objects
    count as of unknown split.
    """
    dirs = [objects_dirs] if isinstance(objects_dirs, (str, os.PathLike)) else list(objects_dirs)
    splits: dict[str, str] = {}
    for d in dirs:
        if not (Path(d) / CATALOG_NAME).exists():
            log.warning("%s: no object catalog, its objects count as of unknown split", d)
            continue
        catalog = read_catalog(d)
        if "split" not in catalog.columns:
            log.warning("%s: the object catalog has no split column, its objects count as of unknown split", d)
            continue
        rows = catalog[catalog["status"] == "ok"] if ok_only else catalog
        for object_id, split in zip(rows["object_id"].astype(str), rows["split"].astype(str)):
            splits.setdefault(object_id, split)
    return splits


def split_by_sdf_grid(assets: list[ObjectAsset]) -> tuple[list[ObjectAsset], dict[str, str]]:
    """The assets whose SDF grid has the most common shape, and the others with their reason.

    One ``SdfBank`` stacks its objects' grids, so they must share one grid size; objects
    prepared at another ``sdf_resolution`` are set aside with a reason, never dropped silently.
    """
    if not assets:
        return [], {}
    shapes = [a.sdf.shape for a in assets]
    common = max(set(shapes), key=lambda shape: (shapes.count(shape), shape))
    kept = [a for a in assets if a.sdf.shape == common]
    set_aside = {a.object_id: f"SDF grid {a.sdf.shape} differs from the shard's {common}" for a in assets if a.sdf.shape != common}
    return kept, set_aside


def available_object_ids(objects_dirs) -> set[str]:
    """Ids of objects whose asset folder holds arrays, over one objects dir or several."""
    dirs = [objects_dirs] if isinstance(objects_dirs, (str, os.PathLike)) else list(objects_dirs)
    ids: set[str] = set()
    for d in dirs:
        root = Path(d) / ASSETS_DIR
        if root.is_dir():
            ids |= {p.name for p in root.iterdir() if (p / "arrays.zarr").exists()}
    return ids


class SdfBank:
    """Signed distance grids of several objects on one device, sampled in a batch.

    ``signed_distance(points, object_index, scale)`` takes points (B, P, 3) in metres in
    each grasp's object frame, the object of each grasp (B,) as an index into this bank,
    and each grasp's scale (B,), and returns the distance in metres (B, P), positive
    inside, with the outward unit normal (B, P, 3). Trilinear interpolation written with
    gathers, so gradients flow to the points. Outside the grid the value at the nearest
    grid point minus the distance to the grid box is used (a continuous lower bound).
    (torch is imported where it is used: preparing objects, which imports this module, needs no torch.)
    """

    def __init__(self, assets: list[ObjectAsset], device: torch.device | str = "cpu", dtype: torch.dtype | None = None) -> None:
        """``dtype``: of the grids (default float32)."""
        import torch

        dtype = torch.float32 if dtype is None else dtype
        if not assets:
            raise ObjectAssetError("SdfBank needs at least one object")
        shapes = {a.sdf.shape for a in assets}
        if len(shapes) != 1:
            raise ObjectAssetError(f"objects have SDF grids of different sizes {sorted(shapes)}; prepare them with one resolution")
        self.object_ids = [a.object_id for a in assets]
        self.index_of = {oid: i for i, oid in enumerate(self.object_ids)}
        self.device = torch.device(device)
        self.resolution = assets[0].sdf.shape[0]
        self.volumes = torch.as_tensor(np.stack([a.sdf for a in assets]), dtype=dtype, device=self.device).reshape(len(assets), -1)
        self.grid_min = torch.as_tensor(np.stack([a.grid_min for a in assets]), dtype=dtype, device=self.device)
        self.voxel_size = torch.as_tensor([a.voxel_size for a in assets], dtype=dtype, device=self.device)

    def indices(self, object_ids) -> torch.Tensor:
        """Bank indices (B,) for a sequence of object ids."""
        import torch

        try:
            return torch.as_tensor([self.index_of[str(o)] for o in object_ids], device=self.device)
        except KeyError as exc:
            raise ObjectAssetError(f"object {exc.args[0]!r} is not in the SDF bank") from None

    def signed_distance(
        self, points_m: torch.Tensor, object_index: torch.Tensor, scale: torch.Tensor, with_normal: bool = True
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Distance (metres, positive inside) and outward normal at ``points_m`` (..., 3).

        ``object_index`` and ``scale`` give each point's object and scale: shape (B,) for
        points (B, P, 3) as in the class doc, or any shape that broadcasts to the points'
        batch shape (e.g. (N,) for a flat (N, 3) list). The grids are indexed in place (no
        per-grasp copy of a grid). ``with_normal=False`` skips the normal (returns None).
        """
        import torch

        g = self.resolution
        shape = points_m.shape[:-1]
        # Per-object and per-scale values stay broadcastable (e.g. (B, 1)): gathered once per grasp, not per point.
        object_index = object_index.reshape(object_index.shape + (1,) * (len(shape) - object_index.dim()))
        s = scale.to(points_m.dtype).reshape(scale.shape + (1,) * (len(shape) - scale.dim()))[..., None]
        local = points_m / s  # normalized frame
        gmin = self.grid_min[object_index]
        h = self.voxel_size[object_index][..., None]
        u = (local - gmin) / h  # continuous grid coordinates
        u_clamped = u.clamp(0.0, g - 1 - 1e-4)
        outside = ((u - u_clamped) * h).norm(dim=-1)
        base_float = u_clamped.detach().floor()
        frac = u_clamped - base_float
        base = base_float.long()
        flat = self.volumes.reshape(-1)
        origin = object_index * (g * g * g) + (base[..., 0] * g + base[..., 1]) * g + base[..., 2]
        fx, fy, fz = frac.unbind(-1)

        # The 8 cell corners in one index_select on the flat grid (~2x faster on CPU than advanced indexing).
        corner_offset = torch.tensor([(di * g + dj) * g + dk for dk in (0, 1) for dj in (0, 1) for di in (0, 1)], device=origin.device)
        corners = flat.index_select(0, (origin.reshape(1, -1) + corner_offset[:, None]).reshape(-1)).reshape(8, *origin.shape)
        c000, c100, c010, c110, c001, c101, c011, c111 = corners.unbind(0)
        c00 = c000 + (c100 - c000) * fx
        c10 = c010 + (c110 - c010) * fx
        c01 = c001 + (c101 - c001) * fx
        c11 = c011 + (c111 - c011) * fx
        c0 = c00 + (c10 - c00) * fy
        c1 = c01 + (c11 - c01) * fy
        value = c0 + (c1 - c0) * fz
        distance_m = (value - outside) * s[..., 0]
        if not with_normal:
            return distance_m, None
        # Analytic gradient of the trilinear interpolant (per unit of grid coordinate).
        gx = ((c100 - c000) * (1 - fy) + (c110 - c010) * fy) * (1 - fz) + ((c101 - c001) * (1 - fy) + (c111 - c011) * fy) * fz
        gy = (c10 - c00) * (1 - fz) + (c11 - c01) * fz
        gz = c1 - c0
        inward = torch.stack([gx, gy, gz], dim=-1)
        away = local - (gmin + u_clamped * h)
        direction = torch.where((outside > 0)[..., None], away, -inward)
        normal = torch.nn.functional.normalize(direction, dim=-1)
        return distance_m, normal
