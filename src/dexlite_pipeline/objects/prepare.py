"""Prepare objects: load, validate, repair, normalize, build assets, split, write the catalog.

Each mesh goes through ``objects.asset_building`` (``load_source_mesh`` -> ``check_shape`` ->
``prepared_solid`` -> ``normalize_mesh`` -> ``objects.build.write_asset``). A mesh that cannot be used is
*rejected* with a one-line reason (``MeshRejected``) and stays in the catalog; one bad
object never stops the others (objects run in a crash-tolerant process pool).
An asset whose inputs (file contents, placement, build settings, the code that builds it
and the versions of trimesh, libigl, CoACD and pymeshfix) are unchanged since it was last written is
reused, so adding a mesh folder rebuilds only the new objects.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import logging
import shutil
import zlib
from pathlib import Path

import numpy as np

from dexlite_pipeline.config import json_ready
from dexlite_pipeline.objects.asset_building import MeshRejected, build_asset
from dexlite_pipeline.objects.asset_settings import AssetBuildSettings
from dexlite_pipeline.objects.assets import ASSETS_DIR, CATALOG_COLUMNS, CATALOG_NAME, asset_dir
from dexlite_pipeline.objects.config import ObjectsConfig
from dexlite_pipeline.objects.sources import MeshSource, pybullet_data_dir

log = logging.getLogger(__name__)

CONFIG_RECORD_NAME = "prepare_config.json"


def file_label(path: str) -> str:
    """The file as shown in the catalog: relative to pybullet_data for embedded meshes."""
    try:
        return f"pybullet_data/{Path(path).resolve().relative_to(pybullet_data_dir().resolve())}"
    except ValueError:
        return str(path)


def builder_version() -> str:
    """Hash of the code that builds an asset (``objects.asset_building`` and what it imports, not the choice of objects
    nor the other config keys) and the versions of the mesh libraries it uses."""
    from importlib.metadata import version

    from dexlite_pipeline.codehash import code_hash

    libraries = {name: version(name) for name in ("trimesh", "libigl", "coacd", "pymeshfix")}
    return f"{code_hash('dexlite_pipeline.objects.asset_building')}-{json.dumps(libraries, sort_keys=True)}"


def _build_key(source: MeshSource, settings: AssetBuildSettings, builder: str) -> str:
    """Hash of everything an asset depends on: file bytes, placement, build settings, builder version."""
    digest = hashlib.sha256()
    digest.update(Path(source.file).read_bytes())
    digest.update(json.dumps([source.scale_xyz, source.rotation_rpy, source.turn_deg, source.metres_per_unit, dataclasses.asdict(settings), builder],
                             sort_keys=True).encode())
    if source.recorded_rest is not None:  # an asset without collision pieces (the key of a full asset is unchanged)
        digest.update(json.dumps(["recorded_rest", source.recorded_rest.as_dict()], sort_keys=True).encode())
    return digest.hexdigest()


def _reusable_asset(objects_dir: Path, object_id: str, key: str, folder: Path | None = None) -> dict | None:
    """The meta of ``object_id``'s asset in ``objects_dir`` (or in ``folder``) when it was built with ``key``, else None."""
    meta_path = (folder if folder is not None else asset_dir(objects_dir, object_id)) / "meta.json"
    if not meta_path.exists() or not (meta_path.parent / "arrays.zarr").exists():
        return None
    try:
        meta = json.loads(meta_path.read_text())
    except (OSError, json.JSONDecodeError):
        return None
    return meta if meta.get("build_key") == key else None


def _row(source: MeshSource, deviation=None, **values) -> dict:
    """The catalog row; ``deviation`` (``fidelity.ShapeDeviation``, or its record from a reused asset's meta.json)
    fills the prepared-versus-input columns."""
    row = {
        "object_id": source.object_id,
        "source": source.source,
        "file": file_label(source.file),
        "watertight": None,
        "volume": float("nan"),
        "n_convex_pieces": 0,
        "status": "rejected",
        "reason": "",
        "preparation": "",
        "surface_deviation": float("nan"),
        "bounds_deviation": float("nan"),
        "volume_ratio": float("nan"),
        "turn_deg": float(source.turn_deg),
    }
    if deviation is not None:
        record = deviation if isinstance(deviation, dict) else deviation.as_record()
        row["surface_deviation"] = _number(max(v for v in (record["surface_p99_in_to_prepared"], record["surface_p99_prepared_to_in"]) if v is not None))
        row["bounds_deviation"] = _number(record["bounds_error"])
        row["volume_ratio"] = _number(record["volume_ratio"])
    row.update(values)
    return row


def _number(value) -> float:
    return float("nan") if value is None else float(value)


def cache_entry(cache_dir: str | Path, object_id: str, key: str) -> Path:
    """Where the shared asset cache (``objects.asset_cache``) keeps ``object_id``'s asset built with ``key``."""
    return Path(cache_dir).expanduser() / object_id / key


def _fetch_cached_asset(cache_dir: str | Path, objects_dir: Path, object_id: str, key: str) -> dict | None:
    """Copy the cache's asset of ``object_id`` built with ``key`` into ``objects_dir`` (atomically); its meta, or None."""
    from dexlite_pipeline.atomic import atomic_path

    entry = cache_entry(cache_dir, object_id, key)
    if _reusable_asset(entry.parent.parent, object_id, key, folder=entry) is None:
        return None
    with atomic_path(asset_dir(objects_dir, object_id)) as tmp:
        shutil.copytree(entry, tmp)
    return _reusable_asset(objects_dir, object_id, key)


def _store_in_cache(cache_dir: str | Path, objects_dir: Path, object_id: str, key: str) -> None:
    """Add the asset just built to the cache (atomically; an entry already there, from a concurrent run, is kept)."""
    import uuid

    entry = cache_entry(cache_dir, object_id, key)
    if entry.is_dir():
        return
    entry.parent.mkdir(parents=True, exist_ok=True)
    tmp = entry.with_name(f".{entry.name}.tmp-{uuid.uuid4().hex[:8]}")
    shutil.copytree(asset_dir(objects_dir, object_id), tmp)
    try:
        tmp.rename(entry)
    except OSError:  # another run stored the same entry first
        shutil.rmtree(tmp, ignore_errors=True)


def prepare_object(source: MeshSource, objects_dir: str, settings: AssetBuildSettings, builder: str = "", cache_dir: str = "") -> dict:
    """Prepare one object; returns its catalog row (status ok, or rejected with the reason).

    ``builder`` (``builder_version()``) enters the reuse key: a code change rebuilds assets. ``cache_dir``
    (``objects.asset_cache``): a folder of assets shared by runs, keyed like the reuse, where an asset not in
    ``objects_dir`` is looked up before it is built, and where one built here is added.
    """
    objects_dir = Path(objects_dir)
    try:
        key = _build_key(source, settings, builder)
        previous = _reusable_asset(objects_dir, source.object_id, key)
        if previous is None and cache_dir:
            previous = _fetch_cached_asset(cache_dir, objects_dir, source.object_id, key)
        if previous is not None:
            return _row(source, previous["deviation"], watertight=bool(previous["watertight"]), volume=float(previous["volume"]),
                        n_convex_pieces=int(previous["n_convex_pieces"]), status="ok", preparation=previous["preparation"]["summary"])
        summary, made, deviation = build_asset(source, objects_dir, settings, key, file_label(source.file))
        if cache_dir:
            _store_in_cache(cache_dir, objects_dir, source.object_id, key)
    except MeshRejected as exc:
        return _row(source, exc.deviation, watertight=False if str(exc).startswith("not watertight") else None, reason=str(exc))
    return _row(source, deviation, watertight=summary["watertight"], volume=summary["volume"],
                n_convex_pieces=summary["n_convex_pieces"], status="ok", preparation=made.summary())


def _already_built(source: MeshSource, objects_dir: Path, settings: AssetBuildSettings, builder: str, cache_dir: str) -> bool:
    """Whether ``prepare_object`` will reuse ``source``'s asset (from ``objects_dir`` or the cache) rather than build it."""
    try:
        key = _build_key(source, settings, builder)
    except OSError:  # an unreadable file: prepare_object records why
        return False
    if _reusable_asset(objects_dir, source.object_id, key) is not None:
        return True
    entry = cache_entry(cache_dir, source.object_id, key) if cache_dir else None
    return entry is not None and _reusable_asset(entry.parent.parent, source.object_id, key, folder=entry) is not None


def _crashed_row(source: MeshSource, message: str) -> dict:
    return _row(source, reason=f"preparation failed: {message.splitlines()[0] if message else 'unknown error'}")


def heldout_ids(sources: list[MeshSource], heldout_fraction: float, seed: int) -> set[str]:
    """The held-out objects: every ``always_heldout`` source plus a seeded ``heldout_fraction`` of the rest.

    Drawn from the sources, before preparation, so a held-out object can be turned before it is
    prepared (``objects.heldout_yaw``); one that is then rejected is held out nowhere.
    """
    always = {s.object_id for s in sources if s.always_heldout}
    candidates = sorted({s.object_id for s in sources} - always)
    n_heldout = int(round(heldout_fraction * len(candidates)))
    rng = np.random.default_rng([seed, 0x5B117])
    return {candidates[i] for i in rng.choice(len(candidates), size=n_heldout, replace=False)} | always


def heldout_turn_deg(object_id: str, seed: int) -> float:
    """A held-out object's seeded yaw, degrees in [0, 360): the same for the same object and seed, whatever else the run holds."""
    return float(np.random.default_rng([seed, 0x7A1E, zlib.crc32(object_id.encode())]).uniform(0.0, 360.0))


def turned_heldout(sources: list[MeshSource], heldout: set[str], seed: int) -> list[MeshSource]:
    """``sources`` with each held-out one turned about z by its seeded yaw (``heldout_turn_deg``)."""
    return [dataclasses.replace(s, turn_deg=heldout_turn_deg(s.object_id, seed)) if s.object_id in heldout else s for s in sources]


def assign_split(catalog, heldout: set[str]):
    """The catalog's split column: "heldout" for ``heldout`` (``heldout_ids``), "train" for the other ok objects;
    rejected objects get an empty split (they are used nowhere)."""
    ok = catalog["status"] == "ok"
    split = np.where(catalog["object_id"].isin(heldout), "heldout", "train")
    catalog["split"] = np.where(ok, split, "")
    return catalog


def remove_stale_assets(objects_dir: Path, keep: set[str]) -> None:
    """Delete asset folders of objects not prepared ok in this run (stale or rejected)."""
    root = objects_dir / ASSETS_DIR
    if not root.is_dir():
        return
    for folder in root.iterdir():
        if folder.is_dir() and folder.name not in keep:
            shutil.rmtree(folder)


def prepare_objects(
    sources: list[MeshSource],
    objects_dir: str | Path,
    config: ObjectsConfig,
    seed: int,
    workers: int,
    catalog_path: str | Path | None = None,
    record_path: str | Path | None = None,
):
    """Prepare every source in parallel into ``objects_dir/assets``, split, write the catalog atomically; returns it.

    The catalog goes to ``catalog_path`` (default ``objects_dir/catalog.parquet``; it must be in
    ``objects_dir``, where readers look for it) and the settings used to ``record_path``
    (default ``objects_dir/prepare_config.json``).
    """
    import pandas as pd

    from dexlite_pipeline.atomic import atomic_path
    from dexlite_pipeline.parallel import resilient_map
    from dexlite_pipeline.progress import ProgressLog

    objects_dir = Path(objects_dir)
    catalog_path = Path(catalog_path) if catalog_path is not None else objects_dir / CATALOG_NAME
    record_path = Path(record_path) if record_path is not None else objects_dir / CONFIG_RECORD_NAME
    if catalog_path.parent.resolve() != objects_dir.resolve() or catalog_path.name != CATALOG_NAME:
        raise ValueError(f"{catalog_path}: the object catalog must be {objects_dir / CATALOG_NAME} (readers find it beside assets/)")
    ids = [s.object_id for s in sources]
    if len(set(ids)) != len(ids):
        raise ValueError(f"duplicate object ids among sources: {sorted({i for i in ids if ids.count(i) > 1})}")
    settings = config.build_settings(seed)
    heldout = heldout_ids(sources, config.heldout_fraction, seed)
    if config.heldout_yaw:
        sources = turned_heldout(sources, heldout, seed)
    objects_dir.mkdir(parents=True, exist_ok=True)
    builder = builder_version()
    task = functools.partial(prepare_object, objects_dir=str(objects_dir), settings=settings, builder=builder,
                             cache_dir=config.asset_cache)

    built = [_already_built(source, objects_dir, settings, builder, config.asset_cache) for source in sources]
    if any(built):
        log.info("preparation: %d of %d objects already built (in %s or the asset cache), %d to build",
                 sum(built), len(sources), objects_dir, len(sources) - sum(built))
    progress = ProgressLog(log, "preparation", len(sources), unit="objects", reusable=sum(built))  # prepared or rejected
    rows = resilient_map(task, sources, workers, _crashed_row, lambda index: progress.advance(reused=built[index]))
    catalog = pd.DataFrame(rows, columns=list(CATALOG_COLUMNS[:-1]))
    catalog["watertight"] = catalog["watertight"].astype("boolean")
    catalog["n_convex_pieces"] = catalog["n_convex_pieces"].astype("int64")
    catalog = assign_split(catalog, heldout)
    catalog = catalog[list(CATALOG_COLUMNS)].sort_values("object_id", kind="stable").reset_index(drop=True)
    remove_stale_assets(objects_dir, set(catalog.loc[catalog["status"] == "ok", "object_id"]))
    with atomic_path(record_path) as tmp:
        tmp.write_text(json.dumps({"seed": seed, "objects": json_ready(config)}, indent=2, sort_keys=True))
    with atomic_path(catalog_path) as tmp:
        catalog.to_parquet(tmp, index=False)
    return catalog
