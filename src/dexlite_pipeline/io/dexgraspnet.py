"""DexGraspNet import and export: its dataset layout <-> grasp store plus object assets.

Layout (a DexGraspNet download)::

    ROOT/dataset/<object_code>.npy                pickled object array of {'qpos': {...}, 'scale': s}
    ROOT/meshdata/<object_code>/coacd/decomposed.obj   convex pieces of the normalized mesh

The grasp files are pickles; they are read with ``io.safe_pickle`` (nothing in them is
executed). ``qpos`` maps one-to-one to ``hand_pose`` (``hand.qpos``: same translation,
same static-axis xyz Euler angles, same joints), so the conversion is exact; the store
keeps float32 as its schema says (relative error below 6e-8). The meshes keep their
frame, in which the grasps are expressed. ``decomposed.obj`` is a set of convex pieces
(its connected components) that touch or overlap; their boolean union (manifold3d) is
the watertight surface the SDF grid and the surface samples are made from: an SDF of
the raw piece soup would measure depth to internal faces, and surface samples would
fall inside the object.

Problems never stop the import: each is a row of the import report (file-level rows
have ``grasp_index`` -1; ``grasps_affected`` is -1 where a failed file's grasp count is
unknown) and everything else is imported.
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.lib import format as npy_format

from dexlite_pipeline.hand.model import JOINT_NAMES
from dexlite_pipeline.hand.qpos import QPOS_KEYS, ROTATION_KEYS, TRANSLATION_KEYS, QposError, hand_pose_from_qpos, qpos_from_hand_pose
from dexlite_pipeline.atomic import atomic_path
from dexlite_pipeline.io.config import DexGraspNetConfig
from dexlite_pipeline.io.grasp_store import (DEFAULT_GRASP_TYPE, DEFAULT_HAND, GRASP_TYPE, GraspSet, empty_grasp_set, grasp_types,
                                             hand_joint_names, store_hand)
from dexlite_pipeline.io.safe_pickle import NpyReadError, RefusedPickleError, load_npy_restricted

log = logging.getLogger(__name__)

SOURCE = "dexgraspnet"
DATASET_DIR = "dataset"
MESHDATA_DIR = "meshdata"
MESH_RELATIVE_PATH = Path("coacd") / "decomposed.obj"
REPORT_COLUMNS = ("file", "object_id", "grasp_index", "grasps_affected", "kind", "reason")
UNKNOWN_GRASP_COUNT = -1  # grasps_affected of a failed file whose header does not say how many grasps it holds
# DexGraspNet writes the joints first, then the palm rotation and translation.
EXPORT_KEY_ORDER = (*JOINT_NAMES, *ROTATION_KEYS, *TRANSLATION_KEYS)


@dataclass
class ImportProblem:
    """One row of the import report: a whole file (grasp_index -1) or one grasp."""

    file: str
    object_id: str
    grasp_index: int
    grasps_affected: int  # grasps not imported because of this problem; UNKNOWN_GRASP_COUNT if not known
    kind: str  # refused_pickle, unreadable_file, wrong_type, missing_mesh, bad_mesh, unknown_joint_names, ...
    reason: str


@dataclass
class GraspFileResult:
    """The grasps of one dataset file that converted, with the problems of the rest."""

    object_id: str
    file: str
    hand_pose: np.ndarray  # (n, 28) float64
    scale: np.ndarray  # (n,) float64
    source_index: np.ndarray  # (n,) int64, position in the file
    problems: list[ImportProblem] = field(default_factory=list)
    grasp_type: list[str] = field(default_factory=list)  # (n,) each grasp's ``grasp_type`` (our export's key), '' where absent


@dataclass
class ImportResult:
    grasps: GraspSet
    catalog: list[dict]
    problems: list[ImportProblem]


def object_split(object_code: str, config: DexGraspNetConfig, seed: int) -> str:
    """'heldout' or 'train': listed codes are held out, others by a seeded hash of the code.

    Hashing each code on its own keeps an object's split when others are added or removed.
    """
    if object_code in config.heldout_object_codes:
        return "heldout"
    digest = hashlib.sha256(f"{seed}:{object_code}".encode()).digest()
    draw = int.from_bytes(digest[:8], "big") / 2.0**64
    return "heldout" if draw < config.heldout_fraction else "train"


def _is_real_number(value) -> bool:
    return not isinstance(value, (bool, np.bool_)) and isinstance(value, (int, float, np.integer, np.floating))


class GraspEntryError(ValueError):
    """One grasp of a dataset file that cannot be used; ``kind`` groups the report rows."""

    def __init__(self, kind: str, reason: str) -> None:
        super().__init__(reason)
        self.kind = kind


def convert_grasp_entry(entry) -> tuple[np.ndarray, float]:
    """One DexGraspNet grasp dict -> (hand_pose float64 (28,), scale); GraspEntryError if unusable."""
    if not isinstance(entry, Mapping):
        raise GraspEntryError("wrong_type", f"grasp is a {type(entry).__name__}, expected a dict with 'qpos' and 'scale'")
    for key in ("qpos", "scale"):
        if key not in entry:
            raise GraspEntryError("wrong_type", f"grasp has no {key!r}")
    qpos, scale = entry["qpos"], entry["scale"]
    if not isinstance(qpos, Mapping):
        raise GraspEntryError("wrong_type", f"qpos is a {type(qpos).__name__}, expected a dict")
    unknown = sorted(str(k) for k in qpos if k not in QPOS_KEYS)
    missing = [k for k in QPOS_KEYS if k not in qpos]
    if unknown:
        also_missing = f"; missing: {', '.join(missing)}" if missing else ""
        raise GraspEntryError("unknown_joint_names", f"unknown qpos keys: {', '.join(unknown)}{also_missing}")
    if missing:
        raise GraspEntryError("missing_joint_names", f"missing qpos keys: {', '.join(missing)}")
    try:
        pose = hand_pose_from_qpos(qpos)
    except QposError as exc:
        kind = "wrong_type" if not all(_is_real_number(v) for v in qpos.values()) else "non_finite"
        raise GraspEntryError(kind, str(exc)) from None
    if not _is_real_number(scale):
        raise GraspEntryError("wrong_type", f"scale is a {type(scale).__name__}, not a number")
    if not math.isfinite(float(scale)) or float(scale) <= 0:
        raise GraspEntryError("bad_scale", f"scale {float(scale)!r} is not a positive finite number")
    return pose, float(scale)


def entry_grasp_type(entry: Mapping) -> str:
    """The ``grasp_type`` our export writes beside ``qpos`` and ``scale`` ('' when the entry has none, as in DexGraspNet's
    own files); GraspEntryError when it is not a non-empty string."""
    if GRASP_TYPE not in entry:
        return ""
    value = entry[GRASP_TYPE]
    if not isinstance(value, str) or not value:
        raise GraspEntryError("wrong_type", f"grasp_type is {value!r}, expected a grasp type name")
    return value


def read_grasp_file(path: Path, root: Path) -> GraspFileResult:
    """Read one ``dataset/<code>.npy`` and convert every grasp it holds that can be used."""
    object_id = path.stem
    label = path.relative_to(root).as_posix()
    result = GraspFileResult(object_id, label, np.zeros((0, 28)), np.zeros(0), np.zeros(0, np.int64))

    def file_problem(kind: str, reason: str, affected: int = 0) -> GraspFileResult:
        result.problems.append(ImportProblem(label, object_id, -1, affected, kind, reason))
        return result

    try:
        entries = load_npy_restricted(path)
    except RefusedPickleError as exc:
        return file_problem("refused_pickle", f"refused pickle global {exc.global_name!r}; nothing was executed")
    except (NpyReadError, OSError) as exc:
        return file_problem("unreadable_file", str(exc))
    if entries.dtype != object or entries.ndim != 1:
        return file_problem("wrong_type", f"file holds a {entries.dtype} array of shape {entries.shape}, expected a list of grasp dicts")
    if len(entries) == 0:
        return file_problem("no_grasps", "file holds no grasps")
    poses, scales, indices = [], [], []
    for index, entry in enumerate(entries):
        try:
            pose, scale = convert_grasp_entry(entry)
            grasp_type = entry_grasp_type(entry)
        except GraspEntryError as exc:
            result.problems.append(ImportProblem(label, object_id, index, 1, exc.kind, str(exc)))
            continue
        poses.append(pose)
        scales.append(scale)
        indices.append(index)
        result.grasp_type.append(grasp_type)
    if poses:
        result.hand_pose = np.stack(poses)
        result.scale = np.asarray(scales)
        result.source_index = np.asarray(indices, np.int64)
    return result


class MeshImportError(ValueError):
    """A DexGraspNet mesh that cannot be turned into an object asset."""


def load_decomposed_mesh(mesh_path: Path):
    """(watertight union mesh, convex pieces) from a CoACD ``decomposed.obj``.

    Pieces are the connected components of the file's faces (vertices are not merged, so
    pieces that touch stay apart). A piece that is not closed is replaced by the convex
    hull of its vertices: CoACD pieces are convex, so this only closes numerical gaps.
    """
    import trimesh

    try:
        soup = trimesh.load(mesh_path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise MeshImportError(f"cannot read mesh: {type(exc).__name__}: {exc}") from None
    if not isinstance(soup, trimesh.Trimesh) or len(soup.faces) == 0:
        raise MeshImportError("mesh has no faces")
    if not np.isfinite(soup.vertices).all():
        raise MeshImportError("mesh has non-finite vertices")
    pieces = []
    for component in soup.split(only_watertight=False):
        piece = trimesh.Trimesh(component.vertices, component.faces, process=True)
        if not piece.is_watertight or piece.volume <= 0:
            piece = trimesh.convex.convex_hull(component.vertices)
        if piece.volume > 0:
            pieces.append(piece)
    if not pieces:
        raise MeshImportError("no convex piece has a positive volume")
    union = pieces[0].copy() if len(pieces) == 1 else trimesh.boolean.union(pieces, engine="manifold")
    if not union.is_watertight or union.volume <= 0:
        raise MeshImportError(f"union of {len(pieces)} convex pieces is not a closed solid")
    return union, pieces


def _catalog_row(object_id: str, mesh_path: Path, split: str, status: str, reason: str = "", summary: dict | None = None) -> dict:
    summary = summary or {}
    return {
        "object_id": object_id,
        "source": SOURCE,
        "file": str(mesh_path),
        "watertight": bool(summary.get("watertight", False)),
        "volume": float(summary.get("volume", float("nan"))),
        "n_convex_pieces": int(summary.get("n_convex_pieces", 0)),
        "status": status,
        "reason": reason,
        # DexGraspNet's mesh and convex pieces are taken as they come (already normalized, grasps made on them):
        # no solid is made and nothing is compared (objects.fidelity)
        "preparation": "imported as given (DexGraspNet's mesh and convex pieces)" if status == "ok" else "",
        "surface_deviation": float("nan"),
        "bounds_deviation": float("nan"),
        "volume_ratio": float("nan"),
        "turn_deg": 0.0,  # as given: its grasps were made in that frame
        "split": split,
    }


@dataclass(frozen=True)
class _FileTask:
    """Everything one worker needs to import one ``dataset/<code>.npy`` and its mesh."""

    path: Path
    root: Path
    objects_out: Path
    settings: object  # objects.config.AssetBuildSettings
    split: str


@dataclass
class _FileOutcome:
    """One file's share of the import: its converted grasps, catalog row and report rows."""

    grasps: GraspFileResult | None  # None: the object was rejected (its catalog row says why)
    catalog_row: dict
    problems: list[ImportProblem]


def _import_file(task: _FileTask) -> _FileOutcome:
    """Convert one grasp file and build its object's asset; never raises for bad data."""
    from dexlite_pipeline.objects.build import write_asset

    result = read_grasp_file(task.path, task.root)
    problems = list(result.problems)
    object_id = result.object_id
    mesh_path = task.root / MESHDATA_DIR / object_id / MESH_RELATIVE_PATH
    count = len(result.source_index)
    if count == 0:
        return _FileOutcome(None, _catalog_row(object_id, mesh_path, task.split, "rejected", "no usable grasps"), problems)
    if not mesh_path.is_file():
        reason = f"missing mesh {mesh_path.relative_to(task.root).as_posix()}"
        problems.append(ImportProblem(result.file, object_id, -1, count, "missing_mesh", reason))
        return _FileOutcome(None, _catalog_row(object_id, mesh_path, task.split, "rejected", reason), problems)
    try:
        mesh, pieces = load_decomposed_mesh(mesh_path)
        meta = {"source": SOURCE, "file": str(mesh_path), "normalization": "dexgraspnet frame kept", "split": task.split}
        summary = write_asset(mesh, object_id, task.objects_out, task.settings, meta, convex_pieces=pieces)
    except Exception as exc:  # one bad object never stops the import; the report names it
        reason = f"mesh unusable: {exc}" if isinstance(exc, MeshImportError) else f"asset build failed: {type(exc).__name__}: {exc}"
        problems.append(ImportProblem(result.file, object_id, -1, count, "bad_mesh", reason))
        return _FileOutcome(None, _catalog_row(object_id, mesh_path, task.split, "rejected", reason), problems)
    return _FileOutcome(result, _catalog_row(object_id, mesh_path, task.split, "ok", summary=summary), problems)


def declared_grasp_count(path: Path) -> int:
    """The number of grasps the ``.npy`` header of ``path`` declares (nothing is unpickled), or UNKNOWN_GRASP_COUNT."""
    try:
        with open(path, "rb") as fp:
            major, _ = npy_format.read_magic(fp)
            read_header = npy_format.read_array_header_1_0 if major == 1 else npy_format.read_array_header_2_0
            shape, _, _ = read_header(fp)
    except (OSError, ValueError):
        return UNKNOWN_GRASP_COUNT
    return int(shape[0]) if len(shape) == 1 else UNKNOWN_GRASP_COUNT


def _crashed_file(task: _FileTask, message: str) -> _FileOutcome:
    """The outcome of a file whose worker raised or died (a native-library crash while building the asset).

    All of the file's grasps are lost; their number is read from the file's header (the
    crash may have come before the grasps were counted).
    """
    object_id = task.path.stem
    mesh_path = task.root / MESHDATA_DIR / object_id / MESH_RELATIVE_PATH
    label = task.path.relative_to(task.root).as_posix()
    reason = f"import failed: {message}"
    problem = ImportProblem(label, object_id, -1, declared_grasp_count(task.path), "import_failed", reason)
    return _FileOutcome(None, _catalog_row(object_id, mesh_path, task.split, "rejected", reason), [problem])


def import_dexgraspnet(
    root: str | os.PathLike, objects_out: str | os.PathLike, settings, config: DexGraspNetConfig, seed: int, workers: int = 1
) -> ImportResult:
    """Read a DexGraspNet download; write object assets under ``objects_out``; return grasps, catalog, problems.

    ``settings`` is an ``objects.config.AssetBuildSettings`` (use the pipeline's, so SDF grids
    match the other objects'). Only objects with at least one usable grasp get an asset.
    Files are imported on ``workers`` processes (1: in this process); the result is in
    file order whatever the number of workers, and a file whose worker crashes is
    reported, not fatal.
    """
    from dexlite_pipeline.parallel import resilient_map
    from dexlite_pipeline.progress import ProgressLog

    root = Path(root)
    dataset = root / DATASET_DIR
    if not dataset.is_dir():
        raise FileNotFoundError(f"{dataset}: no such folder (expected a DexGraspNet download with dataset/ and meshdata/)")
    files = sorted(dataset.glob("*.npy"))
    if not files:
        raise FileNotFoundError(f"{dataset}: no .npy grasp files")
    tasks = [_FileTask(path, root, Path(objects_out), settings, object_split(path.stem, config, seed)) for path in files]

    progress = ProgressLog(log, "import", len(tasks), unit="files")
    outcomes = resilient_map(_import_file, tasks, workers if workers > 1 else 0, _crashed_file, lambda index: progress.advance())
    problems = [problem for outcome in outcomes for problem in outcome.problems]
    kept = [outcome.grasps for outcome in outcomes if outcome.grasps is not None]
    return ImportResult(_grasp_set(kept), [outcome.catalog_row for outcome in outcomes], problems)


def _grasp_set(results: list[GraspFileResult]) -> GraspSet:
    if not results:
        grasps = empty_grasp_set()
        grasps.arrays["source_file"] = np.zeros(0, dtype=object)
        grasps.arrays["source_index"] = np.zeros(0, np.int64)
        return grasps
    counts = [len(r.source_index) for r in results]
    return GraspSet(
        {
            "hand_pose": np.concatenate([r.hand_pose for r in results]).astype(np.float32),
            "object_id": np.repeat(np.asarray([r.object_id for r in results], dtype=object), counts),
            "scale": np.concatenate([r.scale for r in results]).astype(np.float32),
            "source_file": np.repeat(np.asarray([r.file for r in results], dtype=object), counts),
            "source_index": np.concatenate([r.source_index for r in results]),
            **_imported_types(results),
        }
    )


def _imported_types(results: list[GraspFileResult]) -> dict[str, np.ndarray]:
    """``grasp_type`` when some imported grasp carries one (a file our export wrote; the others power), else nothing: a
    DexGraspNet download holds power grasps, which a store without the array means."""
    types = [t for r in results for t in r.grasp_type]
    if not any(types):
        return {}
    return {GRASP_TYPE: np.asarray([t or DEFAULT_GRASP_TYPE for t in types], dtype=object)}


def write_table_atomic(rows: list[dict], columns: tuple[str, ...], path: str | os.PathLike) -> None:
    """Write rows as CSV or Parquet (by suffix) atomically, with the given columns even when empty."""
    import pandas as pd

    frame = pd.DataFrame(rows, columns=list(columns))
    with atomic_path(path) as tmp:
        if Path(path).suffix == ".parquet":
            frame.to_parquet(tmp, index=False)
        else:
            frame.to_csv(tmp, index=False)


def problem_rows(problems: list[ImportProblem]) -> list[dict]:
    return [dataclasses.asdict(p) for p in problems]


def _check_file_name(object_id: str) -> None:
    if not object_id or "/" in object_id or "\\" in object_id or object_id.startswith("."):
        raise ValueError(f"object id {object_id!r} cannot be used as a DexGraspNet file name")


def _write_decomposed_obj(pieces_paths: list[Path], path: Path) -> None:
    """Concatenate convex piece OBJ files into one OBJ with an ``o convex_i`` group each (CoACD's layout)."""
    import trimesh

    lines, offset = [], 1
    for i, piece_path in enumerate(pieces_paths):
        piece = trimesh.load(piece_path, force="mesh", process=False)
        lines.append(f"o convex_{i}")
        lines.extend(f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in piece.vertices)
        lines.extend(f"f {a + offset} {b + offset} {c + offset}" for a, b, c in piece.faces)
        offset += len(piece.vertices)
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")


def export_dexgraspnet(grasps: GraspSet, out_dir: str | os.PathLike, objects_dirs=None) -> dict:
    """Write ``OUT_DIR/dataset/<object_id>.npy`` (DexGraspNet's list of {'qpos', 'scale', 'grasp_type'} dicts).

    ``grasp_type`` (power, pinch, tripod or lateral: ``grasp_store.grasp_types``, power for a store without types) is
    a key DexGraspNet's own files lack; readers that take ``qpos`` and ``scale`` by name are unaffected.

    With ``objects_dirs``, also ``OUT_DIR/meshdata/<object_id>/coacd/decomposed.obj`` from each
    object's convex pieces, so the output is a complete DexGraspNet layout. Returns counts
    and the ids whose asset was not found. A store of another hand (its ``hand`` attribute): ``qpos`` names the hand's
    joints and ``OUT_DIR/hand.json`` records it (``io.hand_export``); DexGraspNet and our import read the Shadow Hand's only.
    """
    from dexlite_pipeline.io.hand_export import hand_qpos, write_hand_record
    from dexlite_pipeline.objects.assets import ObjectAssetError, find_asset_dir

    out_dir = Path(out_dir)
    object_ids = np.asarray([str(o) for o in grasps.object_id])
    types = grasp_types(grasps)
    hand, joint_names = store_hand(grasps.attrs), hand_joint_names(grasps.attrs)
    missing_assets = []
    for object_id in set(object_ids):
        _check_file_name(object_id)  # all before writing anything
    for object_id in sorted(set(object_ids)):
        rows = np.nonzero(object_ids == object_id)[0]
        entries = np.empty(len(rows), dtype=object)
        for k, row in enumerate(rows):
            qpos = qpos_from_hand_pose(grasps.hand_pose[row]) if hand == DEFAULT_HAND else hand_qpos(grasps.hand_pose[row], joint_names)
            entries[k] = {"qpos": {key: qpos[key] for key in EXPORT_KEY_ORDER} if hand == DEFAULT_HAND else qpos, "scale": np.float64(grasps.scale[row]),
                          GRASP_TYPE: str(types[row])}
        with atomic_path(out_dir / DATASET_DIR / f"{object_id}.npy") as tmp:
            with open(tmp, "wb") as fp:
                np.save(fp, entries, allow_pickle=True)
        if objects_dirs:
            try:
                directory = find_asset_dir(objects_dirs, object_id)
            except ObjectAssetError:
                missing_assets.append(object_id)
                continue
            pieces = sorted((directory / "convex").glob("*.obj")) or [directory / "mesh.obj"]
            _write_decomposed_obj(pieces, out_dir / MESHDATA_DIR / object_id / MESH_RELATIVE_PATH)
    if hand != DEFAULT_HAND:
        write_hand_record(out_dir, grasps.attrs, hand, joint_names)
    return {"objects": len(set(object_ids)), "grasps": len(object_ids), "missing_assets": missing_assets}


def import_download(root: str, grasps_out: str, catalog_path: str, report_path: str, seed: int, objects: dict,
                    section: DexGraspNetConfig, workers: int = 1) -> dict:
    """Import the download at ``root``: the grasp store, the object assets beside ``catalog_path``
    (``assets/``) with the catalog, and the import report CSV; returns the import's counts.

    ``objects``: the config section ``objects``, of which ``config.IMPORT_ASSET_KEYS`` set the SDF
    grid and surface samples (equal to the pipeline's, so that grids match).
    """
    from dexlite_pipeline.config import IMPORT_ASSET_KEYS, json_ready
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.objects.assets import CATALOG_COLUMNS, CATALOG_NAME
    from dexlite_pipeline.objects.config import AssetBuildSettings

    if Path(catalog_path).name != CATALOG_NAME:
        raise ValueError(f"{catalog_path}: the object catalog must be named {CATALOG_NAME} (readers find it beside assets/)")
    settings = AssetBuildSettings(**{k: objects[k] for k in IMPORT_ASSET_KEYS if k in objects}, seed=seed)
    objects_dir = Path(catalog_path).parent
    result = import_dexgraspnet(root, objects_dir, settings, section, seed, workers=workers)
    write_table_atomic(result.catalog, CATALOG_COLUMNS, catalog_path)
    write_table_atomic(problem_rows(result.problems), REPORT_COLUMNS, report_path)
    counts = {
        "objects_imported": sum(row["status"] == "ok" for row in result.catalog),
        "objects": len(result.catalog),
        "grasps_imported": len(result.grasps),
        "grasps_not_imported": sum(p.grasps_affected for p in result.problems if p.grasps_affected != UNKNOWN_GRASP_COUNT),
        "files_not_read": sum(p.grasp_index == -1 and p.grasps_affected == 0 for p in result.problems),
        "failed_files_with_unknown_grasp_count": sum(p.grasps_affected == UNKNOWN_GRASP_COUNT for p in result.problems),
        "problems": len(result.problems),
    }
    attrs = {
        "stage": "import_dexgraspnet",
        "source": "dexgraspnet",
        "source_root": str(Path(root).resolve()),
        "config": {"seed": seed, "dexgraspnet": json_ready(section), "asset_settings": json_ready(settings)},
        **{k: v for k, v in counts.items() if k not in ("objects", "problems")},
    }
    write_grasp_store(grasps_out, result.grasps, attrs)
    return counts
