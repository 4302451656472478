"""Checks of what a batch brings (grasp arrays, object rows, batch record), each failure one line naming the key.

Everything is checked before anything is written, so a refused batch leaves the dataset as it was.
"""

from __future__ import annotations

import dataclasses

import math
from collections.abc import Mapping
from datetime import datetime

import numpy as np
import pandas as pd

from dexlite_pipeline.dataset.layout import (
    BATCH_ARRAY,
    BATCH_KIND_PATTERN,
    GRASP_TYPE_ARRAY,
    OBJECT_COMPUTED_COLUMNS,
    OBJECT_OPTIONAL_FLOAT_COLUMNS,
    OBJECT_OPTIONAL_TEXT_COLUMNS,
    OBJECT_REQUIRED_COLUMNS,
    OPTIONAL_ARRAYS,
    REQUIRED_ARRAYS,
    SPLITS,
    STORED_ARRAYS,
    SUPPORT_PLANE_ARRAYS,
    ArraySpec,
    BatchRecord,
    canonical_json,
    default_rebuild,
)


class DatasetError(ValueError):
    """A batch, object table or dataset that breaks the dataset's rules (the message is one line)."""


def fixed_width_strings(values, name: str) -> np.ndarray:
    """Strings as a fixed-width unicode array (stored without pickle); DatasetError if an element is not a str."""
    array = np.asarray(values)
    if array.dtype.kind == "U":
        return array
    if array.dtype.kind != "O" or not all(isinstance(v, str) for v in array.ravel()):
        raise DatasetError(f"grasps: array {name!r} has dtype {array.dtype}, expected strings")
    width = max((len(v) for v in array.ravel()), default=0)
    return np.asarray(array.tolist(), dtype=f"<U{max(1, width)}").reshape(array.shape)


def _converted(name: str, value, spec: ArraySpec, rows: int) -> np.ndarray:
    array = np.asarray(value)
    expected = (rows, *spec.trailing_shape)
    if array.shape != expected:
        raise DatasetError(f"grasps: array {name!r} has shape {array.shape}, expected {expected}")
    if spec.kind == "str":
        return fixed_width_strings(array, name)
    if spec.kind == "bool":
        if array.dtype.kind != "b":
            raise DatasetError(f"grasps: array {name!r} has dtype {array.dtype}, expected bool")
        return array.astype(bool)
    if array.dtype.kind not in "fiu":
        raise DatasetError(f"grasps: array {name!r} has dtype {array.dtype}, expected numbers ({spec.kind})")
    return array.astype(spec.kind)


def normalize_grasp_arrays(arrays: Mapping[str, np.ndarray], pose_width: int | None = None) -> dict[str, np.ndarray]:
    """The batch's arrays in the stored dtypes (float32, bool, fixed-width strings), checked against the schema.

    ``pose_width``: numbers in one ``hand_pose`` (6 + J for the batch's hand; None: the Shadow Hand's 28).
    Required arrays must all be there, the support plane's two both or neither, ``grasp_type`` without empty names; the
    arrays the dataset assigns (``distinct_label``, and ``batch`` of a loaded set) are dropped.
    Held grasps (``lift_success``) must have a finite pose and a positive finite scale.
    """
    missing = [name for name in REQUIRED_ARRAYS if name not in arrays]
    if missing:
        raise DatasetError(f"grasps: missing required array{'s' if len(missing) > 1 else ''}: {', '.join(missing)}")
    unknown = sorted(set(arrays) - set(STORED_ARRAYS) - {BATCH_ARRAY})
    if unknown:
        raise DatasetError(f"grasps: arrays not in the dataset schema: {', '.join(unknown)} (optional ones: {', '.join(OPTIONAL_ARRAYS)})")
    given_plane = [name for name in SUPPORT_PLANE_ARRAYS if name in arrays]
    if given_plane and len(given_plane) != len(SUPPORT_PLANE_ARRAYS):
        absent = [name for name in SUPPORT_PLANE_ARRAYS if name not in arrays]
        raise DatasetError(f"grasps: {', '.join(given_plane)} given without {', '.join(absent)} (a support plane needs both)")
    hand_pose = np.asarray(arrays["hand_pose"])
    rows = int(hand_pose.shape[0]) if hand_pose.ndim else 0
    out = {}
    for name, spec in {**REQUIRED_ARRAYS, **OPTIONAL_ARRAYS}.items():
        if name == "hand_pose" and pose_width is not None:
            spec = dataclasses.replace(spec, trailing_shape=(int(pose_width),))
        if name in arrays:
            out[name] = _converted(name, arrays[name], spec, rows)
    for name in ("object_id", GRASP_TYPE_ARRAY):
        if name in out and rows and (out[name] == "").any():
            raise DatasetError(f"grasps: array {name!r} has {int((out[name] == '').sum())} empty values")
    held = out["lift_success"]
    bad_pose = held & ~np.isfinite(out["hand_pose"]).all(axis=1)
    if bad_pose.any():
        raise DatasetError(f"grasps: array 'hand_pose' has non-finite values in {int(bad_pose.sum())} held grasps (lift_success)")
    bad_scale = held & ~(np.isfinite(out["scale"]) & (out["scale"] > 0))
    if bad_scale.any():
        raise DatasetError(f"grasps: array 'scale' is not positive and finite in {int(bad_scale.sum())} held grasps (lift_success)")
    return out


def normalize_objects_frame(objects: pd.DataFrame | None) -> pd.DataFrame:
    """The batch's object rows with every identity column (OBJECT_COLUMNS but scales and batch), checked.

    ``None`` or an empty frame without columns: the batch brings no new objects (a loop round on present ones).
    Required: object_id, source, split (train / heldout). Optional: rebuild (default: ``default_rebuild``),
    real_radius_m, the support plane and the resting pose (NaN when absent). Columns the dataset
    computes (scales, batch) are ignored; any other column is an error.
    """
    if objects is None or (isinstance(objects, pd.DataFrame) and objects.empty and len(objects.columns) == 0):
        objects = pd.DataFrame({c: pd.Series([], dtype=object) for c in OBJECT_REQUIRED_COLUMNS})  # no new objects
    if not isinstance(objects, pd.DataFrame):
        raise DatasetError(f"objects: expected a pandas DataFrame, got {type(objects).__name__}")
    missing = [c for c in OBJECT_REQUIRED_COLUMNS if c not in objects.columns]
    if missing:
        raise DatasetError(f"objects: missing column{'s' if len(missing) > 1 else ''}: {', '.join(missing)}")
    known = (*OBJECT_REQUIRED_COLUMNS, *OBJECT_OPTIONAL_TEXT_COLUMNS, *OBJECT_OPTIONAL_FLOAT_COLUMNS, *OBJECT_COMPUTED_COLUMNS)
    unknown = [str(c) for c in objects.columns if c not in known]
    if unknown:
        raise DatasetError(f"objects: columns not in the dataset schema: {', '.join(unknown)} (known: {', '.join(known)})")
    frame = pd.DataFrame({c: [_text(v) for v in objects[c]] for c in OBJECT_REQUIRED_COLUMNS}, dtype=object)
    if (frame["object_id"] == "").any():
        raise DatasetError("objects: column 'object_id' has empty ids")
    duplicated = sorted(set(frame["object_id"][frame["object_id"].duplicated()]))
    if duplicated:
        raise DatasetError(f"objects: object ids listed more than once: {', '.join(duplicated)}")
    bad_split = sorted(set(frame["split"]) - set(SPLITS))
    if bad_split:
        raise DatasetError(f"objects: column 'split' has {', '.join(map(repr, bad_split))}; expected {' or '.join(SPLITS)}")
    given_rebuild = [_text(v) for v in objects["rebuild"]] if "rebuild" in objects.columns else [""] * len(frame)
    frame["rebuild"] = [given or default_rebuild(o, s) for given, o, s in zip(given_rebuild, frame["object_id"], frame["source"])]
    for column in OBJECT_OPTIONAL_FLOAT_COLUMNS:
        if column not in objects.columns:
            frame[column] = np.full(len(frame), np.nan)
            continue
        try:
            frame[column] = pd.to_numeric(pd.Series(objects[column].to_numpy()), errors="raise").astype(np.float64).to_numpy()
        except (ValueError, TypeError):
            raise DatasetError(f"objects: column {column!r} has values that are not numbers") from None
    return frame


def _text(value) -> str:
    """A table cell as text: '' for a missing value."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return str(value)


def _check_timestamp(value: str, key: str) -> None:
    try:
        datetime.fromisoformat(str(value).replace("Z", "+00:00"))
    except ValueError:
        raise DatasetError(f"record: {key} {value!r} is not an ISO 8601 timestamp") from None


def check_record(record: BatchRecord) -> None:
    """DatasetError naming the field of ``record`` that cannot go into batches.csv."""
    if not isinstance(record, BatchRecord):
        raise DatasetError(f"record: expected a BatchRecord, got {type(record).__name__}")
    if not BATCH_KIND_PATTERN.match(str(record.kind)):
        raise DatasetError(f"record: kind {record.kind!r} is not optimization, model or loop_round_<r>")
    _check_timestamp(record.started_utc, "started_utc")
    _check_timestamp(record.finished_utc, "finished_utc")
    if not isinstance(record.cpu_seconds, Mapping):
        raise DatasetError("record: cpu_seconds must map stage names to CPU seconds")
    for stage, seconds in record.cpu_seconds.items():
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float, np.integer, np.floating)) or not math.isfinite(seconds) or seconds < 0:
            raise DatasetError(f"record: cpu_seconds[{stage!r}] = {seconds!r} is not a non-negative number of seconds")
    if not isinstance(record.config, Mapping):
        raise DatasetError("record: config must be a mapping (the batch's full config)")
    try:
        canonical_json(record.config)
    except (TypeError, ValueError) as exc:
        raise DatasetError(f"record: config is not JSON-serializable: {exc}") from None
    for key in ("code_version", "machine", "protocol"):
        if not isinstance(getattr(record, key), str):
            raise DatasetError(f"record: {key} must be a string")

