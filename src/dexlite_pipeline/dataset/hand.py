"""Which hand a dataset's batches are of: one hand per dataset folder.

A batch's grasp archive (``grasps/batch_NNNN.npz``) of a hand other than the Shadow Hand holds, beside its per-grasp
arrays, ``HAND_MEMBERS``: ``hand`` (one string: a hand name, or an MJCF file's path), ``joint_names`` (J strings, the
pose's joints in order; a pose is 6 + J numbers) and, for a file, ``hand_sha256`` (one string: its bytes' SHA-256). A batch without them is
the Shadow Hand's (every batch written before hands were recorded, and every Shadow Hand batch since: their files are
unchanged). A dataset holds one hand's grasps: an addition of another hand's batch is refused with the reason, so
Allegro's and LEAP's grasps go in datasets of their own. Records here are the grasp stores' (``io.grasp_store``):
``{}`` for the Shadow Hand, else ``{"hand", "joint_names"[, "hand_sha256"]}``.
"""

from __future__ import annotations

import numpy as np

from dexlite_pipeline.io.grasp_store import DEFAULT_HAND, HAND, GraspStoreError, check_one_hand, hand_joint_names, store_hand

HAND_MEMBERS = ("hand", "joint_names", "hand_sha256")  # per-batch (not per-grasp) members of a batch's archive


def hand_attrs(attrs: dict) -> dict:
    """The hand record of a grasp set's attributes as a dataset keeps it: {} for the Shadow Hand (or no ``hand``), else
    ``hand``, ``joint_names`` and ``hand_sha256`` when given."""
    name = store_hand(attrs or {})
    if name == DEFAULT_HAND:
        return {}
    record = {HAND: name, "joint_names": [str(j) for j in hand_joint_names(attrs)]}
    if attrs.get("hand_sha256"):
        record["hand_sha256"] = str(attrs["hand_sha256"])
    return record


def hand_members(record: dict) -> dict[str, np.ndarray]:
    """The archive members that record ``record`` (``hand_attrs``'s form): none for the Shadow Hand."""
    if not record:
        return {}
    members = {"hand": np.asarray([str(record[HAND])]), "joint_names": np.asarray([str(j) for j in record["joint_names"]])}
    if record.get("hand_sha256"):
        members["hand_sha256"] = np.asarray([str(record["hand_sha256"])])
    return members


def split_hand_members(arrays: dict[str, np.ndarray]) -> tuple[dict[str, np.ndarray], dict]:
    """A batch archive's arrays without ``HAND_MEMBERS``, and the hand record they held ({} when none: the Shadow Hand)."""
    if "hand" not in arrays:
        return {k: v for k, v in arrays.items() if k not in HAND_MEMBERS}, {}
    record = {HAND: _one(arrays["hand"]), "joint_names": [str(j) for j in np.asarray(arrays.get("joint_names", ())).tolist()]}
    if "hand_sha256" in arrays:
        record["hand_sha256"] = _one(arrays["hand_sha256"])
    return {k: v for k, v in arrays.items() if k not in HAND_MEMBERS}, record


def _one(member: np.ndarray) -> str:
    """The one string of a (1,) (or 0-d) archive member."""
    return str(np.asarray(member).reshape(-1)[0])


def one_hand(named_records: list[tuple[str, dict]]) -> dict:
    """The hand record (``hand_attrs``'s form) every (name, record) pair shares; ``ValueError`` in one line naming the first
    two that differ. No pairs: the Shadow Hand ({})."""
    if not named_records:
        return {}
    try:
        return hand_attrs(check_one_hand(named_records))
    except GraspStoreError as exc:
        raise ValueError(f"{exc}: a dataset holds one hand's grasps") from None


def dataset_hand_text(record: dict) -> str:
    """The hand of a dataset in words: the Shadow Hand's 22 joints, or the recorded hand and its joint count."""
    if not record:
        return "the Shadow Hand (a pose: palm position, xyz Euler angles, 22 joint angles)"
    return f"hand {record[HAND]} (a pose: palm position, xyz Euler angles, {len(record['joint_names'])} joint angles: {', '.join(record['joint_names'])})"
