"""Which hand a model file or a set of grasp stores is of, and the one-line refusals when it is not the run's hand.

A hand record is what a grasp store (``io.grasp_store``) and a model file (``model.checkpoint``) keep of their hand:
``hand`` (a name, or an MJCF file's path with ``hand_sha256``, its bytes' SHA-256) and ``joint_names`` in pose order
(``hand.choice.hand_record`` makes it from config key ``hand``). Two records name one hand when their names (or file
contents) and joints agree.
"""

from __future__ import annotations

import os

from dexlite_pipeline.hand.model import JOINT_NAMES
from dexlite_pipeline.io.grasp_store import DEFAULT_HAND, HAND, GraspStoreError, check_one_hand, hand_identity, store_hand


def shadow_hand_record() -> dict:
    """The hand record of a Shadow Hand model (and of a model file that records no hand: every file written before)."""
    return {HAND: DEFAULT_HAND, "joint_names": list(JOINT_NAMES)}


def recorded_hand(entries: dict) -> dict:
    """The hand record a model or evaluator file's entries hold ({"hand", "joint_names"[, "hand_sha256"]}); the Shadow
    Hand's when they name none."""
    if HAND not in entries:
        return shadow_hand_record()
    record = {HAND: str(entries[HAND]), "joint_names": [str(name) for name in entries.get("joint_names") or ()]}
    if entries.get("hand_sha256"):
        record["hand_sha256"] = str(entries["hand_sha256"])
    return record


def same_hand(first: dict, second: dict) -> bool:
    """Whether two hand records name one hand: the same name, or the same file's bytes, and the same joints in order."""
    return hand_identity(first) == hand_identity(second) and list(first["joint_names"]) == list(second["joint_names"])


def hand_mismatch(path: str | os.PathLike, model_hand: dict, wanted_hand: dict) -> str:
    """One line refusing model file ``path`` of hand ``model_hand`` for a run of hand ``wanted_hand`` ("" when they agree)."""
    if same_hand(model_hand, wanted_hand):
        return ""
    have, want = store_hand(model_hand), store_hand(wanted_hand)
    if have == want:
        return f"{path}: a model of hand {have} with another file or joints than this run's hand {want} (the hand file changed): train a model for it"
    return f"{path}: a model of hand {have}, this run's hand is {want}: train a model for hand {want} (config key hand)"


def shards_hand(named_attrs: list[tuple[str, dict]], hand: str | None = None) -> dict:
    """The hand record ({"hand", "joint_names"[, "hand_sha256"]}) that grasp stores given as (path, attributes) share
    ({} for none); ``GraspStoreError`` in one line when two differ (``grasp_store.check_one_hand``) or, with ``hand``
    (config key ``hand``), when theirs is another hand."""
    if not named_attrs:
        return {}
    record = check_one_hand(named_attrs)
    if hand is not None:
        from dexlite_pipeline.hand.choice import hand_record

        if not same_hand(record, hand_record(hand)):
            raise GraspStoreError(f"{named_attrs[0][0]} holds grasps of hand {record[HAND]}, config key hand is {hand}: "
                                  "give the lift shards of that hand")
    return record
