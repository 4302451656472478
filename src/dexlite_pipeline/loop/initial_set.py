"""Round 0's grasp set (stage ``loop_initial_set``): the lift-successful grasps of the training objects the
first model was trained on."""

from __future__ import annotations

import numpy as np

from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.loop.round_basics import TRAIN
from dexlite_pipeline.loop.round_set import round_grasp_set


def initial_set(lift_paths: list[str], objects_dirs: list[str], hand: str | None = None) -> GraspSet:
    """Round 0's grasp set: the lift-successful grasps of prepared training objects in the lift shards
    (what the first model trains on), with their contacts (-1 for imported grasps) and ``round`` 0.

    The shards must be of one hand and, with ``hand`` (config key ``hand``), of that hand (``GraspStoreError`` in one
    line otherwise); the set's attributes are that hand's record (``hand``, ``joint_names``), its poses 6 + J numbers."""
    from dexlite_pipeline.hand.choice import hand_record
    from dexlite_pipeline.model.trainer import read_lift_shards
    from dexlite_pipeline.objects.assets import available_object_ids, object_splits

    lifted = read_lift_shards(lift_paths, hand)
    record = dict(lifted.attrs) or (hand_record(hand) if hand is not None else None)
    if not len(lifted):
        return round_grasp_set({}, 0, record)
    train_ids = {oid for oid, split in object_splits(objects_dirs).items() if split == TRAIN} & available_object_ids(objects_dirs)
    keep = np.asarray(lifted.arrays["lift_success"], bool) & np.isin(lifted.object_id.astype(str), sorted(train_ids))
    keep &= np.isfinite(lifted.hand_pose).all(axis=1)
    return round_grasp_set({k: lifted.arrays[k][keep] for k in ("hand_pose", "object_id", "scale", "contact_index")}, 0, record)
