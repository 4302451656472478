"""A round's grasp set: the grasps the round's model trains on, each with the round that added it."""

from __future__ import annotations

import numpy as np

from dexlite_pipeline.io.grasp_store import GraspSet

SET_ARRAYS = ("hand_pose", "object_id", "scale", "lift_success", "contact_index", "round")  # the arrays of a round's grasp set


def round_grasp_set(arrays: dict, round_number: int) -> GraspSet:
    """A round set's arrays (``SET_ARRAYS``) from hand_pose, object_id, scale and contact_index (absent: none)."""
    n = len(arrays.get("hand_pose", ()))
    return GraspSet({
        "hand_pose": np.asarray(arrays.get("hand_pose", np.zeros((0, 28))), np.float32).reshape(n, 28),
        "object_id": np.asarray(arrays.get("object_id", ()), dtype=object),
        "scale": np.asarray(arrays.get("scale", ()), np.float32),
        "lift_success": np.ones(n, bool),
        "contact_index": np.asarray(arrays.get("contact_index", np.full((n, 4), -1)), np.int64).reshape(n, 4),
        "round": np.full(n, round_number, np.int64),
    }, {})  # fmt: skip
