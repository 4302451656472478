"""Grasp stores: one Zarr v3 group per shard (the layout is described in README.md, "Grasp store layout").

Arrays: ``hand_pose`` float32 (N, D), ``object_id`` (N,) strings, ``scale`` float32 (N,),
and any further per-grasp arrays with first dimension N. Root attributes:
``joint_names`` and ``schema_version``, plus whatever the writing stage records
(its config, provenance).

The hand (config key ``hand``; ``hand.choice.hand_record``): attribute ``hand`` names it (``shadow``, ``allegro``,
``leap``, or an MJCF file's path with ``hand_sha256``, its bytes' SHA-256) and ``joint_names`` its joints in pose
order; a pose is then 6 + J numbers (palm translation, xyz Euler angles, the J joints). A store without ``hand`` is
the Shadow Hand's (every store written before hands were recorded, DexGraspNet imports): D = 28 and the Shadow
Hand's 22 joint names, as a store recording ``hand: shadow``. Stages that combine stores refuse stores of different
hands (``check_one_hand``).

``grasp_type`` (N,) strings: the grasp type optimization from scratch made the grasp as (``power``, ``pinch``,
``tripod``, ``lateral``: ``optim.grasp_types``); every optimized store has it, and curation and the lift test carry it.
A store without it holds power grasps (all stores written before grasp types existed, DexGraspNet imports):
``grasp_types`` reads it so, and ``GraspSet.concatenate_common`` fills it so for such inputs (``ARRAY_DEFAULTS``).
"""

from __future__ import annotations

import json
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexlite_pipeline.atomic import atomic_path
from dexlite_pipeline.hand.model import JOINT_NAMES, POSE_DIM

SCHEMA_VERSION = 1
REQUIRED_ARRAYS = ("hand_pose", "object_id", "scale")
GRASP_TYPE = "grasp_type"  # the array naming each grasp's type
DEFAULT_GRASP_TYPE = "power"  # the type of a grasp in a store without ``grasp_type``
# Per-grasp arrays whose absence means a known value: concatenating a store that has one with one that lacks it
# fills the value in rather than leaving the array out.
ARRAY_DEFAULTS: dict[str, str] = {GRASP_TYPE: DEFAULT_GRASP_TYPE}


HAND = "hand"  # the attribute naming a store's hand
DEFAULT_HAND = "shadow"  # the hand of a store without ``hand``
POSE_PREFIX = 6  # palm translation (3) and Euler angles (3) before a hand's joints in a pose


class GraspStoreError(ValueError):
    """A grasp store that cannot be read or written as the schema requires."""


@dataclass
class GraspSet:
    """Per-grasp arrays (all with first dimension N) and the store's root attributes."""

    arrays: dict[str, np.ndarray]
    attrs: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.arrays["hand_pose"].shape[0])

    @property
    def hand_pose(self) -> np.ndarray:
        return self.arrays["hand_pose"]

    @property
    def object_id(self) -> np.ndarray:
        return self.arrays["object_id"]

    @property
    def scale(self) -> np.ndarray:
        return self.arrays["scale"]

    def select(self, mask_or_index: np.ndarray) -> "GraspSet":
        """A new set holding the chosen grasps (boolean mask or integer index)."""
        return GraspSet({k: v[mask_or_index] for k, v in self.arrays.items()}, dict(self.attrs))

    @staticmethod
    def concatenate(sets: list["GraspSet"], attrs: dict | None = None) -> "GraspSet":
        """Concatenate sets that hold the same arrays (empty list gives an empty set)."""
        if not sets:
            return empty_grasp_set(attrs)
        keys = set(sets[0].arrays)
        for s in sets[1:]:
            if set(s.arrays) != keys:
                raise GraspStoreError(f"cannot concatenate grasp sets with different arrays: {sorted(keys)} vs {sorted(s.arrays)}")
        arrays = {k: np.concatenate([s.arrays[k] for s in sets]) for k in sets[0].arrays}
        return GraspSet(arrays, dict(attrs if attrs is not None else sets[0].attrs))

    @staticmethod
    def concatenate_common(sets: list["GraspSet"]) -> tuple["GraspSet", list[str]]:
        """The sets with rows concatenated on the arrays they all have, and the names of the arrays left out.

        Sets without rows add no grasps and take no part in choosing the arrays (a shard
        written empty without some array must not strip it from the others). With no rows
        at all, the first set (or an empty set) is returned as it is. An array of
        ``ARRAY_DEFAULTS`` that some sets lack is filled with its default for their rows.
        """
        with_rows = [s for s in sets if len(s)]
        if not with_rows:
            return (GraspSet(dict(sets[0].arrays), {}) if sets else empty_grasp_set()), []
        for name, value in ARRAY_DEFAULTS.items():  # an array with a known default is filled in where a set lacks it
            if any(name in s.arrays for s in with_rows):
                with_rows = [s if name in s.arrays else GraspSet({**s.arrays, name: np.full(len(s), value, dtype=object)}, s.attrs)
                             for s in with_rows]
        shared = set.intersection(*(set(s.arrays) for s in with_rows))
        left_out = sorted(set.union(*(set(s.arrays) for s in with_rows)) - shared)
        return GraspSet.concatenate([GraspSet({k: s.arrays[k] for k in shared}) for s in with_rows], attrs={}), left_out


def grasp_types(grasps: GraspSet) -> np.ndarray:
    """(N,) each grasp's type (strings): its ``grasp_type``, or ``power`` for every grasp of a store without one."""
    if GRASP_TYPE in grasps.arrays:
        return np.asarray([str(t) for t in grasps.arrays[GRASP_TYPE]], dtype=object)
    return np.full(len(grasps), DEFAULT_GRASP_TYPE, dtype=object)


def store_hand(attrs: dict) -> str:
    """The hand a store's attributes name: ``hand``, or ``shadow`` for a store without it."""
    return str(attrs.get(HAND) or DEFAULT_HAND)


def hand_identity(attrs: dict) -> str:
    """What makes two stores' hands the same: a file's SHA-256 (whatever its path), else the hand's name."""
    return str(attrs.get("hand_sha256") or store_hand(attrs))


def hand_joint_names(attrs: dict) -> list[str]:
    """The joints of a store's hand in pose order: its ``joint_names`` for a recorded non-Shadow hand, else the Shadow Hand's."""
    if store_hand(attrs) == DEFAULT_HAND:
        return list(JOINT_NAMES)
    names = attrs.get("joint_names")
    if not names:
        raise GraspStoreError(f"hand {store_hand(attrs)}: a store of a hand other than shadow must record its joint_names")
    return [str(n) for n in names]


def pose_width(attrs: dict) -> int:
    """Numbers in one pose of a store with attributes ``attrs``: 28 for the Shadow Hand, 6 + J for another hand."""
    return POSE_DIM if store_hand(attrs) == DEFAULT_HAND else POSE_PREFIX + len(hand_joint_names(attrs))


def check_one_hand(named_attrs: list[tuple[str, dict]]) -> dict:
    """The hand record (``hand``, ``hand_sha256`` when a file, ``joint_names``) that every (name, attributes) pair shares;
    ``GraspStoreError`` naming the first two that differ (a stage must not mix grasps of two hands)."""
    if not named_attrs:
        return {HAND: DEFAULT_HAND, "joint_names": list(JOINT_NAMES)}
    first_name, first = named_attrs[0]
    for name, attrs in named_attrs[1:]:
        if hand_identity(attrs) != hand_identity(first) and store_hand(attrs) == store_hand(first):
            raise GraspStoreError(f"{first_name} and {name} name hand {store_hand(first)} with different file contents (SHA-256 "
                                  f"{str(first.get('hand_sha256'))[:12]} vs {str(attrs.get('hand_sha256'))[:12]}): the file changed")
        if hand_identity(attrs) != hand_identity(first):
            raise GraspStoreError(f"{first_name} holds grasps of hand {store_hand(first)}, {name} of hand {store_hand(attrs)}: "
                                  "grasps of different hands are not combined")
    record = {HAND: store_hand(first), "joint_names": hand_joint_names(first)}
    if first.get("hand_sha256"):
        record["hand_sha256"] = str(first["hand_sha256"])
    return record


def empty_grasp_set(attrs: dict | None = None) -> GraspSet:
    """A set without grasps; its pose width follows the hand ``attrs`` name (``pose_width``)."""
    return GraspSet(
        {
            "hand_pose": np.zeros((0, pose_width(attrs or {})), np.float32),
            "object_id": np.zeros((0,), dtype=object),
            "scale": np.zeros((0,), np.float32),
        },
        dict(attrs or {}),
    )


def _normalize(arrays: dict[str, np.ndarray], width: int = POSE_DIM, hand: str = DEFAULT_HAND) -> dict[str, np.ndarray]:
    missing = [k for k in REQUIRED_ARRAYS if k not in arrays]
    if missing:
        raise GraspStoreError(f"missing required arrays: {', '.join(missing)}")
    hand_pose = np.asarray(arrays["hand_pose"], dtype=np.float32)
    if hand_pose.ndim != 2 or hand_pose.shape[1] != width:
        raise GraspStoreError(f"hand_pose has shape {hand_pose.shape}, expected (N, {width}) for hand {hand}")
    n = hand_pose.shape[0]
    out = {"hand_pose": hand_pose}
    for key, value in arrays.items():
        if key == "hand_pose":
            continue
        value = np.asarray(value)
        if value.ndim == 0 or value.shape[0] != n:
            raise GraspStoreError(f"array {key!r} has shape {value.shape}, expected first dimension {n}")
        if key == "object_id" or value.dtype.kind in "UOT":
            value = np.asarray([str(v) for v in value], dtype=object)
        elif key == "scale":
            value = value.astype(np.float32)
        out[key] = value
    return out


def write_grasp_store(path: str | os.PathLike, grasps: GraspSet, attrs: dict | None = None) -> Path:
    """Write ``grasps`` to a Zarr v3 store at ``path`` atomically; returns the path.

    ``attrs`` are merged over ``grasps.attrs``; they must be JSON-serializable. Their ``hand`` (and for a hand other
    than shadow its ``joint_names``) sets the pose width the grasps must have; without ``hand``, the Shadow Hand's.
    """
    import zarr

    root_attrs = {**grasps.attrs, **(attrs or {})}
    arrays = _normalize(grasps.arrays, pose_width(root_attrs), store_hand(root_attrs))
    root_attrs["joint_names"] = hand_joint_names(root_attrs)
    root_attrs["schema_version"] = SCHEMA_VERSION
    try:
        json.dumps(root_attrs)
    except TypeError as exc:
        raise GraspStoreError(f"{path}: attributes are not JSON-serializable: {exc}") from exc
    final = Path(path)
    with atomic_path(final) as tmp:
        group = zarr.open_group(str(tmp), mode="w", zarr_format=3)
        n = arrays["hand_pose"].shape[0]
        chunk_rows = max(1, min(n, 65536))
        for key, value in arrays.items():
            if value.dtype == object:
                arr = group.create_array(key, shape=value.shape, dtype=str, chunks=(chunk_rows,))
                if n:
                    arr[:] = value
            else:
                arr = group.create_array(key, shape=value.shape, dtype=value.dtype, chunks=(chunk_rows, *value.shape[1:]))
                if n:
                    arr[:] = value
        group.attrs.update(root_attrs)
    return final


def read_grasp_store(path: str | os.PathLike) -> GraspSet:
    """Read a whole grasp store into memory, checking the schema."""
    import zarr

    p = Path(path)
    if not p.exists():
        raise GraspStoreError(f"{p}: no such grasp store")
    try:
        group = zarr.open_group(str(p), mode="r")
    except Exception as exc:  # zarr raises several types for a non-store folder
        raise GraspStoreError(f"{p}: not a Zarr grasp store ({exc})") from exc
    arrays = {}
    with warnings.catch_warnings():
        # Snakemake marks directory outputs with a .snakemake_timestamp file, which zarr
        # warns about while listing the group; it is not part of the store.
        warnings.filterwarnings("ignore", message=r"Object at \.snakemake_timestamp is not recognized")
        keys = list(group.array_keys())
    for key in keys:
        value = group[key][...]
        if value.dtype.kind in "UOT":
            value = np.asarray([str(v) for v in value.tolist()], dtype=object).reshape(value.shape)
        arrays[key] = value
    missing = [k for k in REQUIRED_ARRAYS if k not in arrays]
    if missing:
        raise GraspStoreError(f"{p}: missing required arrays: {', '.join(missing)}")
    attrs = dict(group.attrs)
    if store_hand(attrs) == DEFAULT_HAND and attrs.get("joint_names") not in (None, list(JOINT_NAMES)):
        raise GraspStoreError(f"{p}: joint_names differ from the Shadow Hand's 22 joints (a store of another hand records it as hand)")
    try:
        width = pose_width(attrs)
    except GraspStoreError as exc:
        raise GraspStoreError(f"{p}: {exc}") from None
    hand_pose = arrays["hand_pose"]
    if hand_pose.ndim != 2 or hand_pose.shape[1] != width:
        raise GraspStoreError(f"{p}: hand_pose has shape {hand_pose.shape}, expected (N, {width}) for hand {store_hand(attrs)}")
    n = hand_pose.shape[0]
    for key, value in arrays.items():
        if value.shape[:1] != (n,):
            raise GraspStoreError(f"{p}: array {key!r} has shape {value.shape}, expected first dimension {n}")
    return GraspSet(arrays, attrs)


def invalid_grasp_reasons(grasps: GraspSet, known_object_ids: set[str] | None = None) -> np.ndarray:
    """Per grasp, '' if usable, else a short reason (non-finite pose/scale, unknown object).

    Stages keep the valid grasps and carry the reasons forward instead of dropping rows.
    """
    n = len(grasps)
    reasons = np.full(n, "", dtype=object)
    finite_pose = np.isfinite(grasps.hand_pose).all(axis=1)
    reasons[~finite_pose] = "non-finite hand_pose"
    scale = grasps.scale.astype(np.float64)
    bad_scale = ~np.isfinite(scale) | (scale <= 0)
    reasons[(reasons == "") & bad_scale] = "non-positive or non-finite scale"
    if known_object_ids is not None:
        unknown = np.array([oid not in known_object_ids for oid in grasps.object_id], dtype=bool)
        reasons[(reasons == "") & unknown] = "object id not in the object assets"
    return reasons
