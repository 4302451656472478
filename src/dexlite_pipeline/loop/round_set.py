"""A round's grasp set: the grasps the round's model trains on, each with the round that added it."""

from __future__ import annotations

import numpy as np

from dexlite_pipeline.io.grasp_store import GraspSet, pose_width

SET_ARRAYS = ("hand_pose", "object_id", "scale", "lift_success", "contact_index", "round")  # the arrays of a round's grasp set


def round_grasp_set(arrays: dict, round_number: int, hand: dict | None = None) -> GraspSet:
    """A round set's arrays (``SET_ARRAYS``) from hand_pose, object_id, scale and contact_index (absent: none).

    ``hand``: the hand record of the poses (``hand``, ``joint_names``; None: the Shadow Hand's), which sets the pose
    width (6 + J numbers) and becomes the set's attributes."""
    n = len(arrays.get("hand_pose", ()))
    width = pose_width(hand or {})
    return GraspSet({
        "hand_pose": np.asarray(arrays.get("hand_pose", np.zeros((0, width))), np.float32).reshape(n, width),
        "object_id": np.asarray(arrays.get("object_id", ()), dtype=object),
        "scale": np.asarray(arrays.get("scale", ()), np.float32),
        "lift_success": np.ones(n, bool),
        "contact_index": np.asarray(arrays.get("contact_index", np.full((n, 4), -1)), np.int64).reshape(n, 4),
        "round": np.full(n, round_number, np.int64),
    }, dict(hand or {}))  # fmt: skip
