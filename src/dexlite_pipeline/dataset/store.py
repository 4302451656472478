"""The grasp dataset: add a batch, load grasps, merge datasets, export to DexGraspNet (layout: ``dataset.layout``).

An addition checks everything first, then writes the batch's grasps and config, then
objects.csv, then batches.csv. batches.csv is the commit point: readers see only the batches it
lists, and object rows of a batch it does not list (an addition that was killed half-way) are
ignored and dropped by the next addition, whose files replace the leftovers. One writer at a time.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd

from dexlite_pipeline.atomic import atomic_path, write_text_atomic
from dexlite_pipeline.dataset.files import read_npz, read_table, write_npz_deterministic, write_table
from dexlite_pipeline.dataset.hand import HAND_MEMBERS, hand_attrs, hand_members, one_hand, split_hand_members
from dexlite_pipeline.dataset.labels import assign_distinct_labels
from dexlite_pipeline.dataset.layout import (
    ASSIGNED_ARRAYS, BATCH_ARRAY, BATCH_COLUMNS, BATCH_INT_COLUMNS, BATCHES_TABLE, GRASP_TYPE_ARRAY, OBJECT_COLUMNS,
    OBJECT_IDENTITY_COLUMNS, OBJECT_OPTIONAL_FLOAT_COLUMNS, OBJECTS_TABLE, OPTIMIZATION_KIND, OPTIONAL_ARRAYS, REQUIRED_ARRAYS,
    ArraySpec, BatchRecord, batch_name, config_path, config_digest, grasps_path,
)  # fmt: skip
from dexlite_pipeline.dataset.validation import DatasetError, check_record, normalize_grasp_arrays, normalize_objects_frame
from dexlite_pipeline.io.grasp_store import GraspSet, pose_width

OBJECT_FLOAT_COLUMNS = OBJECT_OPTIONAL_FLOAT_COLUMNS  # real_radius_m, support plane, resting pose
# Two runs' rest pose and support plane of one object can differ by about a micrometre or a microradian (the table test
# in PyBullet of the same asset, run again): identity floats (metres, unit-vector and quaternion components) agree
# within this absolute tolerance (10 um, 10 urad), far below anything a grasp resolves (the lift test's start cap: 2 mm).
OBJECT_FLOAT_TOLERANCE = 1e-5
OBJECT_LIST_LIMIT = 300  # characters of batches.csv's compact object list before "... (+k more)"


def read_batches(dataset_dir: str | os.PathLike) -> pd.DataFrame:
    """batches.csv (empty table when there is none); ``batch`` stays the zero-padded text."""
    return read_table(Path(dataset_dir) / BATCHES_TABLE, BATCH_COLUMNS, int_columns=BATCH_INT_COLUMNS)


def read_objects(dataset_dir: str | os.PathLike, batches: pd.DataFrame | None = None) -> pd.DataFrame:
    """objects.csv without the rows of batches batches.csv does not list (left by an addition that did not finish)."""
    batches = read_batches(dataset_dir) if batches is None else batches
    objects = read_table(Path(dataset_dir) / OBJECTS_TABLE, OBJECT_COLUMNS, float_columns=OBJECT_FLOAT_COLUMNS)
    return objects[objects["batch"].isin(set(batches["batch"]))].reset_index(drop=True)


def batch_ids(batches: pd.DataFrame) -> list[int]:
    return [int(b) for b in batches["batch"]]


def present_objects(dataset_dir: str | os.PathLike) -> set[str]:
    """Ids of the objects in the dataset (none when the folder or its tables do not exist yet)."""
    return set(read_objects(dataset_dir)["object_id"])


def compact_object_list(object_ids, limit: int = OBJECT_LIST_LIMIT) -> str:
    """Ids in a short text: numbered ids of one prefix as ranges ("household-mug-000..004,007"), others as they are."""
    numbered: dict[str, list[str]] = {}
    plain = []
    for object_id in sorted(set(object_ids)):
        match = re.fullmatch(r"(.*-)(\d+)", object_id)
        if match:
            numbered.setdefault(match.group(1), []).append(match.group(2))
        else:
            plain.append(object_id)
    parts = []
    for prefix, numbers in sorted(numbered.items()):
        runs: list[list[str]] = []
        for number in sorted(numbers, key=lambda n: (int(n), n)):
            if runs and int(number) == int(runs[-1][-1]) + 1:
                runs[-1].append(number)
            else:
                runs.append([number])
        parts.append(prefix + ",".join(run[0] if len(run) == 1 else f"{run[0]}..{run[-1]}" for run in runs))
    parts = sorted(parts + plain)
    text = ""
    for shown, part in enumerate(parts):
        candidate = f"{text}; {part}" if text else part
        if len(candidate) > limit:
            return f"{text} ... (+{len(parts) - shown} more)"
        text = candidate
    return text


def _identity_differences(stored: pd.Series, given: pd.Series) -> list[str]:
    """Identity columns whose values differ between two rows of one object (NaN equals NaN; floats within
    ``OBJECT_FLOAT_TOLERANCE`` of each other are equal)."""
    differ = []
    for column in OBJECT_IDENTITY_COLUMNS:
        a, b = stored[column], given[column]
        if column in OBJECT_FLOAT_COLUMNS:
            if not (np.isnan(a) and np.isnan(b)) and not abs(a - b) <= OBJECT_FLOAT_TOLERANCE:
                differ.append(column)
        elif str(a) != str(b):
            differ.append(column)
    return differ


def _check_objects(kind: str, frame: pd.DataFrame, grasp_objects: list[str], stored: pd.DataFrame, allow_present: bool) -> None:
    """DatasetError when the batch's objects clash with the dataset's (see ``add_batch``)."""
    by_id = stored.set_index("object_id", drop=False)
    if kind == OPTIMIZATION_KIND and not allow_present:
        again = sorted((set(frame["object_id"]) | set(grasp_objects)) & set(by_id.index))
        if again:
            first = again[0]
            more = f" (and {len(again) - 1} more)" if len(again) > 1 else ""
            raise DatasetError(f"object {first}{more} is already in the dataset (batch {by_id.loc[first, 'batch']}); "
                               "an optimization batch must not recompute objects present")  # fmt: skip
    for _, row in frame.iterrows():
        if row["object_id"] in by_id.index:
            differ = _identity_differences(by_id.loc[row["object_id"]], row)
            if differ:
                raise DatasetError(f"object {row['object_id']}: {', '.join(differ)} differ from the dataset's row (batch {by_id.loc[row['object_id'], 'batch']})")
    unlisted = sorted(set(grasp_objects) - set(frame["object_id"]) - set(by_id.index))
    if unlisted:
        raise DatasetError(f"object {unlisted[0]} has grasps but no row in the objects frame" + (f" (and {len(unlisted) - 1} more)" if len(unlisted) > 1 else ""))


def _scales_text(scales) -> str:
    """Sorted distinct finite scales as "0.08;0.1" (each float32 in its shortest text)."""
    values = np.unique(np.asarray(scales, np.float32))
    return ";".join(str(s) for s in values[np.isfinite(values)])


def add_batch(dataset_dir: str | os.PathLike, grasps: GraspSet, objects: pd.DataFrame | None, record: BatchRecord) -> int:
    """Add one finished batch to the dataset at ``dataset_dir`` (created if needed); returns its batch id.

    ``grasps``: every grasp of the batch, held or not, with the arrays of ``layout.REQUIRED_ARRAYS``
    (and optionally ``OPTIONAL_ARRAYS``), in the batch's preferred order (best first: the first
    grasp of a new distinct grasp represents it). ``objects``: one row per object the batch ran
    (``validation.normalize_objects_frame``); objects already present need no row (None: no new
    objects). An ``optimization`` batch must not hold an object already in the dataset;
    ``loop_round_<r>`` and ``model`` batches may add grasps to present objects. Held grasps get
    distinct labels consistent with the dataset (``labels.assign_distinct_labels``), others -1.
    Nothing is written unless every check passes.
    """
    return _add_batch(Path(dataset_dir), grasps, objects, record, allow_present=False)


def _labelled_grasps_and_scales(
    dataset_dir: Path, batches: pd.DataFrame, object_ids: set[str], width: int = 28
) -> tuple[dict, dict[str, list]]:
    """The dataset's held (labelled) grasps of ``object_ids`` in dataset order, and every object's stored scales
    (``width``: numbers in a pose of the dataset's hand).

    Poses are read only from batches that hold such grasps (an optimization batch, of new objects, reads none).
    """
    known: dict[str, list[np.ndarray]] = {key: [] for key in ("object_id", "scale", "hand_pose", "distinct_label")}
    scales_of: dict[str, list[np.ndarray]] = {}
    for previous in batch_ids(batches):
        old = read_npz(grasps_path(dataset_dir, previous), ("object_id", "scale", "distinct_label"))
        for object_id in np.unique(old["object_id"]):
            scales_of.setdefault(str(object_id), []).append(old["scale"][old["object_id"] == object_id])
        mine = np.isin(old["object_id"], list(object_ids)) & (old["distinct_label"] >= 0)
        if mine.any():
            old.update(read_npz(grasps_path(dataset_dir, previous), ("hand_pose",)))
            for key in known:
                known[key].append(old[key][mine])
    empty = {"object_id": np.zeros(0, str), "scale": np.zeros(0, np.float32), "hand_pose": np.zeros((0, width), np.float32),
             "distinct_label": np.zeros(0, np.int32)}  # fmt: skip
    return {key: np.concatenate(parts) if parts else empty[key] for key, parts in known.items()}, scales_of


def _batch_row(name: str, record: BatchRecord, arrays: dict[str, np.ndarray], batch_objects: list[str], added: int) -> dict:
    """The batch's row of batches.csv."""
    return {
        "batch": name, "kind": record.kind, "n_objects": len(batch_objects), "objects": compact_object_list(batch_objects),
        "grasps": len(arrays["object_id"]), "held": int(arrays["lift_success"].sum()), "distinct_held_added": added,
        "code_version": record.code_version, "config_digest": config_digest(record.config), "machine": record.machine,
        "cpu_seconds": json.dumps({str(k): float(v) for k, v in record.cpu_seconds.items()}, sort_keys=True, separators=(",", ":")),
        "started_utc": record.started_utc, "finished_utc": record.finished_utc, "protocol": record.protocol,
    }  # fmt: skip


def _add_batch(dataset_dir: Path, grasps: GraspSet, objects: pd.DataFrame | None, record: BatchRecord, allow_present: bool) -> int:
    """``add_batch``; ``allow_present``: an optimization batch may hold present objects too (a merge)."""
    check_record(record)
    if not isinstance(grasps, GraspSet):
        raise DatasetError(f"grasps: expected a GraspSet, got {type(grasps).__name__}")
    hand = hand_attrs(grasps.attrs)  # {} for the Shadow Hand
    arrays = normalize_grasp_arrays(grasps.arrays, pose_width(hand))
    frame = normalize_objects_frame(objects)
    batches = read_batches(dataset_dir)
    stored = read_objects(dataset_dir, batches)
    dataset_hand = stored_hand(dataset_dir, batches)
    if batch_ids(batches) and one_hand_or_none([("dataset", dataset_hand), ("batch", hand)]) is None:
        raise DatasetError(f"{dataset_dir}: holds grasps of {hand_label(dataset_hand)}, this batch is of {hand_label(hand)}: a dataset holds "
                           "one hand's grasps (add it to a dataset folder of its own)")
    grasp_objects = sorted(set(arrays["object_id"].tolist()))
    _check_objects(record.kind, frame, grasp_objects, stored, allow_present)

    known, scales_of = _labelled_grasps_and_scales(dataset_dir, batches, set(grasp_objects), pose_width(hand))
    arrays["distinct_label"], added = assign_distinct_labels(
        known["object_id"], known["scale"], known["hand_pose"], known["distinct_label"],
        arrays["object_id"], arrays["scale"], arrays["hand_pose"], arrays["lift_success"],
    )  # fmt: skip
    for object_id in grasp_objects:
        scales_of.setdefault(object_id, []).append(arrays["scale"][arrays["object_id"] == object_id])

    batch_id = max(batch_ids(batches), default=0) + 1
    name = batch_name(batch_id)
    new_rows = frame[~frame["object_id"].isin(set(stored["object_id"]))].sort_values("object_id", kind="stable").copy()
    new_rows["batch"] = name
    table = pd.concat([stored, new_rows], ignore_index=True) if len(stored) else new_rows.reset_index(drop=True)
    table["scales"] = [_scales_text(np.concatenate(scales_of[o])) if o in scales_of else "" for o in table["object_id"]]
    row = pd.DataFrame([_batch_row(name, record, arrays, sorted(set(frame["object_id"]) | set(grasp_objects)), added)])
    batches = pd.concat([batches, row], ignore_index=True) if len(batches) else row

    write_npz_deterministic(grasps_path(dataset_dir, batch_id), {**arrays, **hand_members(hand)})  # a Shadow Hand batch: no hand members
    config_text = json.dumps(record.config, sort_keys=True, indent=2, default=_json_default, allow_nan=True) + "\n"
    write_text_atomic(config_path(dataset_dir, batch_id), config_text)
    write_table(table, OBJECT_COLUMNS, dataset_dir / OBJECTS_TABLE)
    write_table(batches, BATCH_COLUMNS, dataset_dir / BATCHES_TABLE)  # last: the commit point
    return batch_id


def _json_default(value):
    """numpy scalars and dataclasses in a config as plain JSON values (``config.json_ready``)."""
    from dexlite_pipeline.config import json_ready

    ready = json_ready(value)
    if ready is value:
        raise TypeError(f"{type(value).__name__} is not JSON-serializable")
    return ready


def _as_loaded(arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Stored strings as object arrays of str, as the project's grasp sets hold them (``io.grasp_store``)."""
    return {k: np.asarray(v.tolist(), dtype=object) if v.dtype.kind == "U" else v for k, v in arrays.items()}


def _empty_arrays() -> dict[str, np.ndarray]:
    out = {}
    for name, spec in {**REQUIRED_ARRAYS, GRASP_TYPE_ARRAY: OPTIONAL_ARRAYS[GRASP_TYPE_ARRAY], **ASSIGNED_ARRAYS}.items():
        dtype = object if spec.kind == "str" else spec.kind
        out[name] = np.zeros((0, *spec.trailing_shape), dtype=dtype)
    out[BATCH_ARRAY] = np.zeros(0, np.int32)
    return out


def _absent_rows(spec: ArraySpec, rows: int) -> np.ndarray:
    """``rows`` rows of an optional array for a batch without it: its ``absent`` value (strings as object arrays)."""
    if spec.kind == "str":
        return np.full(rows, spec.absent, dtype=object)
    return np.full((rows, *spec.trailing_shape), spec.absent, spec.kind)


def load_batch(dataset_dir: str | os.PathLike, batch_id: int) -> GraspSet:
    """Every grasp of one batch as stored (strings as object arrays), with ``batch``; its attributes name the batch and,
    for a hand other than the Shadow Hand, its hand record (``dataset.hand``)."""
    arrays, hand = split_hand_members(read_npz(grasps_path(dataset_dir, batch_id)))
    arrays = _as_loaded(arrays)
    arrays[BATCH_ARRAY] = np.full(len(arrays["object_id"]), int(batch_id), np.int32)
    return GraspSet(arrays, {"batch": batch_name(batch_id), **hand})


def batch_hand(dataset_dir: str | os.PathLike, batch_id: int) -> dict:
    """The hand record of one batch (``dataset.hand``: {} for the Shadow Hand), read without its grasps."""
    return split_hand_members(read_npz(grasps_path(dataset_dir, batch_id), HAND_MEMBERS))[1]


def stored_hand(dataset_dir: str | os.PathLike, batches: pd.DataFrame | None = None) -> dict:
    """The hand record the dataset's batches share ({} for the Shadow Hand, and for a dataset without batches);
    ``DatasetError`` in one line naming two batches of different hands."""
    batches = read_batches(dataset_dir) if batches is None else batches
    named = [(f"batch {batch_name(b)}", batch_hand(dataset_dir, b)) for b in batch_ids(batches)]
    try:
        return one_hand(named)
    except ValueError as exc:
        raise DatasetError(f"{dataset_dir}: {exc}") from None


def one_hand_or_none(named: list[tuple[str, dict]]) -> dict | None:
    """``one_hand`` of the records, or None when they differ."""
    try:
        return one_hand(named)
    except ValueError:
        return None


def hand_label(record: dict) -> str:
    """A hand record in a message: "hand shadow" or "hand NAME"."""
    return f"hand {record.get('hand', 'shadow')}"


def load_dataset(dataset_dir: str | os.PathLike, object_ids=None, held_only: bool = False) -> tuple[GraspSet, pd.DataFrame]:
    """The dataset's grasps (of ``object_ids`` when given; only the held ones with ``held_only``) and its object rows.

    Grasps come in dataset order (batch, then row), with the stored arrays (strings as object
    arrays of str), ``distinct_label`` and ``batch`` (int32). A support-plane array that some
    batches lack is NaN in their rows. ``grasp_type`` is always there: a batch made before grasp
    types existed (no ``grasp_type``) holds power grasps, the only type optimization then made
    (``layout.GRASP_TYPE_ABSENT``). Object rows: objects.csv, restricted to ``object_ids``. The set's attributes are
    the dataset's hand record (``dataset.hand``: {} for the Shadow Hand; poses of 6 + J numbers for another hand).
    """
    dataset_dir = Path(dataset_dir)
    if not (dataset_dir / BATCHES_TABLE).is_file():
        raise DatasetError(f"{dataset_dir}: no {BATCHES_TABLE}: not a grasp dataset (add_batch makes one)")
    batches = read_batches(dataset_dir)
    objects = read_objects(dataset_dir, batches)
    hand = stored_hand(dataset_dir, batches)
    if object_ids is not None:
        wanted = {str(o) for o in ([object_ids] if isinstance(object_ids, str) else object_ids)}
        unknown = sorted(wanted - set(objects["object_id"]))
        if unknown:
            raise DatasetError(f"{dataset_dir}: objects not in the dataset: {', '.join(unknown)}")
        objects = objects[objects["object_id"].isin(wanted)].reset_index(drop=True)
    parts = []
    for batch_id in batch_ids(batches):
        arrays = load_batch(dataset_dir, batch_id).arrays
        keep = np.ones(len(arrays["object_id"]), bool)
        if object_ids is not None:
            keep &= np.isin(arrays["object_id"].astype(str), list(wanted))
        if held_only:
            keep &= arrays["lift_success"]
        parts.append({k: v[keep] for k, v in arrays.items()})
    if not parts:
        return GraspSet(_empty_arrays(), hand), objects
    for name, spec in OPTIONAL_ARRAYS.items():
        if name == GRASP_TYPE_ARRAY or any(name in p for p in parts):
            for p in parts:
                p.setdefault(name, _absent_rows(spec, len(p["object_id"])))
    return GraspSet({k: np.concatenate([p[k] for p in parts]) for k in parts[0]}, hand), objects


def _record_of(dataset_dir: Path, row: pd.Series) -> BatchRecord:
    """The BatchRecord a batches.csv row and its config file give back."""
    config = json.loads(config_path(dataset_dir, int(row["batch"])).read_text())
    return BatchRecord(kind=row["kind"], code_version=row["code_version"], config=config, cpu_seconds=json.loads(row["cpu_seconds"]),
                       started_utc=row["started_utc"], finished_utc=row["finished_utc"], protocol=row["protocol"], machine=row["machine"])  # fmt: skip


def merge_datasets(sources: list, dest: str | os.PathLike) -> dict[str, dict[int, int]]:
    """Append every batch of each source dataset, in order, to ``dest`` (created if needed); returns {source: {old id: new id}}.

    Batches are renumbered after dest's. An object in several datasets must have the same
    identity columns everywhere (else DatasetError naming it, nothing written); its grasps are
    then relabelled with dest's distinct labels as an addition would. Dest is rebuilt in a
    temporary folder and swapped in, so a failed merge leaves it as it was. CARD.md is not
    rewritten (``card.write_card``).
    """
    dest = Path(dest)
    sources = [Path(s) for s in sources]
    for source in sources:
        if source.resolve() == dest.resolve():
            raise DatasetError(f"{source}: a dataset cannot be merged into itself")
        if not (source / BATCHES_TABLE).is_file():
            raise DatasetError(f"{source}: no {BATCHES_TABLE}: not a grasp dataset")
    seen: dict[str, tuple[Path, pd.Series]] = {}
    for where in [dest, *sources]:
        for _, row in read_objects(where).iterrows():
            if row["object_id"] in seen:
                first_place, first_row = seen[row["object_id"]]
                differ = _identity_differences(first_row, row)
                if differ:
                    raise DatasetError(f"object {row['object_id']}: {', '.join(differ)} differ between {first_place} and {where}")
            else:
                seen[row["object_id"]] = (where, row)
    renumbered: dict[str, dict[int, int]] = {}
    with atomic_path(dest) as tmp:
        if dest.is_dir():
            shutil.copytree(dest, tmp)
        else:
            tmp.mkdir(parents=True)
        for source in sources:
            batches = read_batches(source)
            objects = read_objects(source, batches)
            mapping = renumbered.setdefault(str(source), {})
            for _, row in batches.iterrows():
                frame = objects[objects["batch"] == row["batch"]].loc[:, list(OBJECT_IDENTITY_COLUMNS)]
                grasps = load_batch(source, int(row["batch"]))
                mapping[int(row["batch"])] = _add_batch(tmp, grasps, frame, _record_of(source, row), allow_present=True)
    return renumbered


def export_dexgraspnet(dataset_dir: str | os.PathLike, out_dir: str | os.PathLike, objects_dirs=None) -> dict:
    """Write the dataset's held grasps in DexGraspNet's layout (``io.dexgraspnet.export_dexgraspnet``, each with its
    ``grasp_type``); returns its counts.

    ``objects_dirs``: prepared objects folders (``<dir>/assets/<object_id>``) whose convex pieces
    become ``meshdata/<object_id>/coacd/decomposed.obj``; without them only ``dataset/`` is written. A dataset of another
    hand than the Shadow Hand: ``qpos`` names its joints and ``hand.json`` records the hand and its joint names.
    """
    from dexlite_pipeline.io.dexgraspnet import export_dexgraspnet as export_grasp_set

    grasps, _ = load_dataset(dataset_dir, held_only=True)
    held = GraspSet({key: grasps.arrays[key] for key in ("hand_pose", "object_id", "scale", GRASP_TYPE_ARRAY)}, grasps.attrs)  # the hand
    return export_grasp_set(held, out_dir, objects_dirs)

