"""A dataset's grasps as a run's training data (stage ``dataset_grasps``, one shard).

A run with ``dataset.root`` prepares its objects as usual (the household generator and the object
sources rebuild the same meshes), and its training objects that the dataset holds take their grasps
from it instead of being optimized again. Every tested grasp comes along, held or not, with its
outcome, so the stores read like the lift-validation shards (training uses the held ones; the learned
evaluator all of them). A grasp only means something on the object it was made on: an object whose
prepared scale or table in this run differs from the dataset's is left out, with the reason.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from dexlite_pipeline.io.grasp_store import GraspSet

log = logging.getLogger(__name__)

SCALE_TOLERANCE = 1e-3  # relative difference between the dataset's scale and the run's real scale of an object
NORMAL_TOLERANCE_DEG = 1.0  # angle between the dataset's and the run's table normal of an object
OFFSET_TOLERANCE_M = 0.001  # difference of the table's height under the object origin (m)


def dataset_training_objects(dataset_dir: str | Path, objects_dirs: list[str]) -> set[str]:
    """The run's training objects (catalog split ``train``, status ok) that the dataset holds: not optimized in the run."""
    from dexlite_pipeline.dataset.store import present_objects
    from dexlite_pipeline.objects.assets import object_splits

    training = {oid for oid, split in object_splits(objects_dirs).items() if split == "train"}
    return training & present_objects(dataset_dir)


def _mismatch(object_id: str, grasps: GraspSet, asset, planes) -> str:
    """Why the dataset's grasps of ``object_id`` do not fit the run's prepared object ('' when they do)."""
    scale = np.asarray(grasps.scale, np.float64)
    real = asset.real_scale
    if real and np.any(np.abs(scale / real - 1.0) > SCALE_TOLERANCE):
        return f"dataset scale {scale.min():.5g} differs from the prepared object's real scale {real:.5g}"
    if planes is None:
        return ""
    if object_id not in planes:
        return "no resting pose in this run's stability table"
    plane = planes.get(object_id)
    normals = np.asarray(grasps.arrays.get("support_normal", np.full((len(grasps), 3), np.nan)), np.float64)
    offsets = np.asarray(grasps.arrays.get("support_offset_m", np.full(len(grasps), np.nan)), np.float64)
    if not np.isfinite(normals).all() or not np.isfinite(offsets).all():
        return "the dataset records no table for its grasps (floating), the run is tabletop"
    angle = np.degrees(np.arccos(np.clip(normals @ np.asarray(plane.normal, np.float64), -1.0, 1.0)))
    offset_m = np.asarray([plane.offset_m(s) for s in scale])
    if angle.max() > NORMAL_TOLERANCE_DEG or np.abs(offsets - offset_m).max() > OFFSET_TOLERANCE_M:
        return f"resting pose differs from the dataset's (table normal {angle.max():.1f} deg, height {1000 * np.abs(offsets - offset_m).max():.1f} mm apart)"
    return ""


def shard_dataset_grasps(
    dataset_dir: str | Path, objects_dirs: list[str], stability_path: str, shard: int, shards: int, table: bool, hand: str = "shadow",
) -> GraspSet:
    """The dataset's grasps of the shard's stable training objects, as a lift-validation shard reads.

    Objects are dealt to shards as in the grasp stages. Attributes: the dataset, the objects taken, the
    objects left out with their reason (not stable, no prepared asset, a scale or table that differs), and the hand
    record (``hand``, ``joint_names``; none for the Shadow Hand). The dataset must be of ``hand`` (config key ``hand``; a
    dataset holds one hand's grasps, ``dataset.hand``): ``DatasetError`` in one line naming both hands otherwise.
    """
    from dexlite_pipeline.dataset.hand import hand_attrs
    from dexlite_pipeline.dataset.store import load_dataset, one_hand_or_none, stored_hand
    from dexlite_pipeline.dataset.validation import DatasetError
    from dexlite_pipeline.hand.choice import hand_record
    from dexlite_pipeline.io.grasp_store import pose_width
    from dexlite_pipeline.objects.assets import ObjectAssetError, load_asset

    record = stored_hand(dataset_dir)
    wanted_hand = hand_attrs(hand_record(hand))
    if one_hand_or_none([(str(dataset_dir), record), ("config key hand", wanted_hand)]) is None:
        raise DatasetError(f"{dataset_dir}: a dataset of hand {record.get('hand', 'shadow')}, config key hand is {hand}: give "
                           "dataset.root a dataset of that hand's grasps (one hand per dataset)")
    from dexlite_pipeline.objects.stability import stable_object_ids
    from dexlite_pipeline.sharding import shard_objects
    from dexlite_pipeline.tabletop import load_support_planes

    present = dataset_training_objects(dataset_dir, objects_dirs)
    stable = stable_object_ids(stability_path)
    mine = shard_objects(sorted(present), shard, shards)
    left_out = {oid: "not stable in this run's stability test" for oid in mine if oid not in stable}
    wanted = [oid for oid in mine if oid in stable]
    planes = load_support_planes(table, stability_path)
    grasps, _ = load_dataset(dataset_dir, wanted) if wanted else (None, None)
    keep = np.zeros(len(grasps) if grasps is not None else 0, bool)
    taken = []
    for object_id in wanted:
        rows = np.flatnonzero(grasps.object_id.astype(str) == object_id)
        if not len(rows):
            left_out[object_id] = "the dataset holds no tested grasp of it (its optimization found none to test)"
            continue
        try:
            asset = load_asset(objects_dirs, object_id)
        except ObjectAssetError as exc:
            left_out[object_id] = f"no prepared asset: {exc}"
            continue
        reason = _mismatch(object_id, grasps.select(rows), asset, planes)
        if reason:
            left_out[object_id] = reason
            continue
        keep[rows] = True
        taken.append(object_id)
    for object_id, reason in left_out.items():
        log.warning("dataset object %s left out: %s", object_id, reason)
    arrays = {name: values[keep] for name, values in grasps.arrays.items()} if grasps is not None else {
        "hand_pose": np.zeros((0, pose_width(record)), np.float32), "object_id": np.zeros(0, dtype=object), "scale": np.zeros(0, np.float32),
        "lift_success": np.zeros(0, bool)}
    held = int(np.asarray(arrays["lift_success"], bool).sum())
    log.info("shard %03d: %d dataset grasps (%d held) of %d objects; %d objects left out", shard, len(arrays["object_id"]), held, len(taken),
             len(left_out))
    attrs = {**record, "stage": "dataset_grasps", "shard": f"{shard:03d}", "dataset": str(dataset_dir), "objects": taken, "left_out_objects": left_out,
             "scene": {"table": bool(table)}}
    return GraspSet(arrays, attrs)
