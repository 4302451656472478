"""What a grasp dataset holds, in numbers: objects, grasps, held and distinct held grasps, per family and batch.

Read from the tables and the grasps' ``object_id``, ``lift_success``, ``distinct_label`` and ``grasp_type`` only
(no poses), so it is quick on a large dataset. An object's distinct held grasps are its number of
distinct labels (``dataset.labels``).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from dexlite_pipeline.dataset.files import read_npz
from dexlite_pipeline.dataset.layout import (
    GRASP_TYPE_ABSENT, GRASP_TYPE_ARRAY, TARGET_DISTINCT_PER_OBJECT, TARGET_OBJECTS, grasps_path, is_household_training, object_family,
)  # fmt: skip
from dexlite_pipeline.dataset.store import batch_ids, read_batches, read_objects


def _spread(values: list[int]) -> dict[str, float]:
    """min / median / max of per-object counts (0 each with no objects)."""
    if not values:
        return {"min": 0, "median": 0.0, "max": 0}
    return {"min": int(min(values)), "median": float(np.median(values)), "max": int(max(values))}


def per_object_counts(dataset_dir: str | os.PathLike) -> dict[str, dict[str, int]]:
    """Per object id of objects.csv: grasps, held grasps and distinct held grasps (0 for an object without grasps)."""
    batches = read_batches(dataset_dir)
    objects = read_objects(dataset_dir, batches)
    counts = {str(o): {"grasps": 0, "held": 0, "distinct_held": 0} for o in objects["object_id"]}
    labels: dict[str, set[int]] = {o: set() for o in counts}
    for batch_id in batch_ids(batches):
        arrays = read_npz(grasps_path(dataset_dir, batch_id), ("object_id", "lift_success", "distinct_label"))
        for object_id in np.unique(arrays["object_id"]):
            mine = arrays["object_id"] == object_id
            entry = counts.setdefault(str(object_id), {"grasps": 0, "held": 0, "distinct_held": 0})
            entry["grasps"] += int(mine.sum())
            entry["held"] += int((mine & arrays["lift_success"]).sum())
            labels.setdefault(str(object_id), set()).update(int(v) for v in arrays["distinct_label"][mine] if v >= 0)
    for object_id, entry in counts.items():
        entry["distinct_held"] = len(labels.get(object_id, ()))
    return counts


def per_type_counts(dataset_dir: str | os.PathLike) -> dict[str, dict[str, int]]:
    """Per grasp type: grasps, held grasps, distinct held grasps and objects with a held grasp of that type.

    A distinct held grasp of a type is an (object, distinct label) pair among its held grasps (labels are per object,
    over every type: a pinch and a power grasp with palms within the distinct-grasp rule share one). A batch without
    ``grasp_type`` holds power grasps (``layout.GRASP_TYPE_ABSENT``). Types in order of first appearance.
    """
    batches = read_batches(dataset_dir)
    counts: dict[str, dict] = {}
    for batch_id in batch_ids(batches):
        arrays = read_npz(grasps_path(dataset_dir, batch_id), ("object_id", "lift_success", "distinct_label", GRASP_TYPE_ARRAY))
        types = arrays.get(GRASP_TYPE_ARRAY, np.full(len(arrays["object_id"]), GRASP_TYPE_ABSENT))
        for name in dict.fromkeys(types.tolist()):
            mine = types == name
            held = mine & arrays["lift_success"]
            entry = counts.setdefault(str(name), {"grasps": 0, "held": 0, "labels": set()})
            entry["grasps"] += int(mine.sum())
            entry["held"] += int(held.sum())
            entry["labels"].update(zip(arrays["object_id"][held].tolist(), arrays["distinct_label"][held].tolist()))
    return {name: {"grasps": e["grasps"], "held": e["held"], "distinct_held": len(e["labels"]),
                   "objects_with_held": len({o for o, _ in e["labels"]})} for name, e in counts.items()}  # fmt: skip


def dataset_summary(dataset_dir: str | os.PathLike) -> dict:
    """The dataset in numbers (JSON-ready).

    Keys: ``objects``, ``objects_by_split``, ``grasps``, ``held``, ``distinct_held`` (totals);
    ``distinct_held_per_object`` (min / median / max over the objects, zeros included);
    ``per_object`` (family, source, split, grasps, held, distinct_held); ``per_family`` (objects,
    grasps, held, distinct_held, its per-object spread, objects at the target); ``per_batch``
    (batches.csv's rows, cpu_seconds as a dict plus ``cpu_seconds_total``); ``target`` (household
    training objects with >= TARGET_DISTINCT_PER_OBJECT distinct held grasps, out of TARGET_OBJECTS);
    ``per_type`` (``per_type_counts``).
    """
    dataset_dir = Path(dataset_dir)
    batches = read_batches(dataset_dir)
    objects = read_objects(dataset_dir, batches)
    counts = per_object_counts(dataset_dir)
    per_object = {}
    for row in objects.itertuples(index=False):
        per_object[row.object_id] = {"family": object_family(row.object_id, row.source), "source": row.source, "split": row.split,
                                     **counts.get(row.object_id, {"grasps": 0, "held": 0, "distinct_held": 0})}  # fmt: skip
    per_family: dict[str, dict] = {}
    for object_id, entry in sorted(per_object.items()):
        family = per_family.setdefault(entry["family"], {"objects": 0, "grasps": 0, "held": 0, "distinct_held": 0, "distinct": [], "at_target": 0})
        family["objects"] += 1
        for key in ("grasps", "held", "distinct_held"):
            family[key] += entry[key]
        family["distinct"].append(entry["distinct_held"])
        family["at_target"] += int(entry["distinct_held"] >= TARGET_DISTINCT_PER_OBJECT)
    for family in per_family.values():
        family["distinct_held_per_object"] = _spread(family.pop("distinct"))
        family["objects_at_target"] = family.pop("at_target")
    per_batch = []
    for row in batches.to_dict("records"):
        seconds = json.loads(row["cpu_seconds"]) if row["cpu_seconds"] else {}
        per_batch.append({**{k: (int(v) if isinstance(v, (np.integer,)) else v) for k, v in row.items()},
                          "cpu_seconds": seconds, "cpu_seconds_total": float(sum(seconds.values()))})  # fmt: skip
    household_training = [o for o, e in per_object.items() if is_household_training(o, e["split"])]
    at_target = [o for o in household_training if per_object[o]["distinct_held"] >= TARGET_DISTINCT_PER_OBJECT]
    training = [o for o, e in per_object.items() if e["split"] == "train"]
    return {
        "objects": len(per_object),
        "objects_by_split": {split: sum(e["split"] == split for e in per_object.values()) for split in ("train", "heldout")},
        "grasps": sum(e["grasps"] for e in per_object.values()),
        "held": sum(e["held"] for e in per_object.values()),
        "distinct_held": sum(e["distinct_held"] for e in per_object.values()),
        "distinct_held_per_object": _spread([e["distinct_held"] for e in per_object.values()]),
        "per_object": per_object,
        "per_family": dict(sorted(per_family.items())),
        "per_batch": per_batch,
        "per_type": per_type_counts(dataset_dir),
        "target": {
            "objects_wanted": TARGET_OBJECTS,
            "distinct_held_wanted": TARGET_DISTINCT_PER_OBJECT,
            "household_training_objects": len(household_training),
            "household_training_objects_at_target": len(at_target),
            "training_objects_at_target": sum(per_object[o]["distinct_held"] >= TARGET_DISTINCT_PER_OBJECT for o in training),
        },
    }
