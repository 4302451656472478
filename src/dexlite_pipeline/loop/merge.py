"""A round's merge (stage ``loop_merge``): the previous round's set plus the validated candidates that are new
distinct grasps (``evaluation.diversity``: not the same grasp as one of the set nor as an earlier pick of the round);
every other candidate gets ``DUPLICATE`` when it passed the checks."""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd

from dexlite_pipeline.config import json_ready
from dexlite_pipeline.evaluation.diversity import DiversityConfig, distinct_grasp_labels, first_of_each_cluster
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store
from dexlite_pipeline.loop.round_basics import DROP_REASONS, DUPLICATE
from dexlite_pipeline.loop.round_set import SET_ARRAYS, round_grasp_set

log = logging.getLogger(__name__)


def new_distinct_grasps(
    known_pose: np.ndarray, known_group: np.ndarray, new_pose: np.ndarray, new_group: np.ndarray, diversity: DiversityConfig
) -> np.ndarray:
    """(M,) bool: which new grasps (in the order given: best first) are distinct grasps the known ones lack.

    Known and new grasps are clustered together (``distinct_grasp_labels``: palms within
    ``distinct_translation_m`` and ``distinct_rotation_deg`` of a cluster's first grasp are that
    grasp; grasps of different groups, e.g. objects and scales, never are), known grasps first: a new
    grasp is kept when it starts a cluster, so it is the same grasp as no known grasp that represents
    one and as no new grasp kept before it, and each kept grasp adds exactly one distinct grasp to the set.
    """
    width = np.shape(new_pose)[-1] if np.ndim(new_pose) == 2 else np.shape(known_pose)[-1]  # 6 + J numbers of the hand
    known_pose = np.asarray(known_pose, np.float64).reshape(-1, width)
    new_pose = np.asarray(new_pose, np.float64).reshape(-1, width)
    groups = np.concatenate([np.asarray(known_group).astype(str), np.asarray(new_group).astype(str)])
    labels = distinct_grasp_labels(np.concatenate([known_pose, new_pose]), groups, diversity.distinct_translation_m, diversity.distinct_rotation_deg)
    kept = np.zeros(len(new_pose), bool)
    firsts = first_of_each_cluster(labels)
    kept[firsts[firsts >= len(known_pose)] - len(known_pose)] = True
    return kept


def grasp_groups(grasps: GraspSet) -> np.ndarray:
    """Per grasp, its object and scale as one key: the groups distinct grasps are counted in (as the evaluation does)."""
    scales = np.asarray(grasps.scale, np.float64).astype(str)
    return np.char.add(np.char.add(np.asarray(grasps.object_id).astype(str), "|"), scales)


def merge_round(
    previous: GraspSet, validated: list[GraspSet], diversity: DiversityConfig, round_number: int, hand: dict | None = None
) -> tuple[GraspSet, GraspSet]:
    """Round ``round_number``'s set and its candidates: ``previous`` plus the validated grasps that are new distinct grasps.

    ``hand``: the hand record the poses are of (``hand``, ``joint_names``; None: the Shadow Hand's), the merged set's
    attributes.
    ``validated``: the round's ``validate_round.validate_round`` shards. Candidates that passed every check are taken best first
    (lowest E_post; ties in shard and row order) and kept by ``new_distinct_grasps``; the others get ``DUPLICATE``.
    Returns the merged set (``SET_ARRAYS``; the kept grasps with ``round`` = ``round_number``) and every candidate
    (object_id, scale, E_post, drop_reason) in shard and row order.
    """
    stores = [v for v in validated if len(v)]
    candidates = GraspSet.concatenate_common(stores)[0] if stores else None
    if candidates is None or not len(candidates):
        return GraspSet(dict(previous.arrays), dict(hand or {})), round_grasp_set({}, round_number, hand)
    reason = np.asarray(candidates.arrays["drop_reason"], dtype=object).copy()
    energy = np.asarray(candidates.arrays.get("E_post", np.zeros(len(candidates))), np.float64)
    passed = np.flatnonzero(reason == "")
    order = passed[np.argsort(np.where(np.isfinite(energy[passed]), energy[passed], np.inf), kind="stable")]
    kept = new_distinct_grasps(previous.hand_pose, grasp_groups(previous), candidates.hand_pose[order], grasp_groups(candidates.select(order)), diversity)
    reason[order[~kept]] = DUPLICATE
    new_rows = np.sort(order[kept])
    contacts = np.asarray(candidates.arrays.get("contact_index", np.full((len(candidates), 4), -1)), np.int64)
    added = round_grasp_set({"hand_pose": candidates.hand_pose[new_rows], "object_id": candidates.object_id[new_rows],
                        "scale": candidates.scale[new_rows], "contact_index": contacts[new_rows]}, round_number, hand)  # fmt: skip
    merged = GraspSet.concatenate([GraspSet({k: previous.arrays[k] for k in SET_ARRAYS}), added], attrs=dict(hand or {}))
    table = GraspSet({"hand_pose": candidates.hand_pose, "object_id": candidates.object_id, "scale": candidates.scale,
                      "E_post": energy, "drop_reason": reason}, {})  # fmt: skip
    log.info("round %d: %d candidates, %d kept (%s)", round_number, len(candidates), len(new_rows),
             ", ".join(f"{r} {int((reason == r).sum())}" for r in DROP_REASONS))
    return merged, table


def merge_round_stores(
    previous_path: str, validated_paths: list[str], diversity: DiversityConfig, round_number: int, hand: str | None = None
) -> tuple[GraspSet, dict]:
    """``merge_round`` of the stores at the paths: the merged set, its candidates as arrays ``candidate_*`` in the attributes' stead.

    The stores must be of one hand and, with ``hand`` (config key ``hand``), of that hand (``GraspStoreError`` in one
    line naming a store and both hands otherwise); the attributes record it (``hand``, ``joint_names``)."""
    from dexlite_pipeline.model.hand_match import shards_hand

    previous, validated = read_grasp_store(previous_path), [read_grasp_store(p) for p in validated_paths]
    record = shards_hand([(previous_path, previous.attrs), *zip(validated_paths, (v.attrs for v in validated))], hand)
    merged, candidates = merge_round(previous, validated, diversity, round_number, record)
    counts = candidate_counts(candidates)
    attrs = {**record, "stage": "loop_merge", "round": int(round_number), "config": {"diversity": json_ready(diversity)},
             "candidates": counts.to_dict("records")}  # fmt: skip
    return merged, attrs


def candidate_counts(candidates: GraspSet) -> pd.DataFrame:
    """Per object: candidates sampled, kept, and dropped per reason (columns ``DROP_REASONS``)."""
    columns = ["object_id", "sampled", "kept", *DROP_REASONS]
    if not len(candidates):
        return pd.DataFrame(columns=columns)
    frame = pd.DataFrame({"object_id": np.asarray(candidates.object_id).astype(str), "reason": np.asarray(candidates.arrays["drop_reason"]).astype(str)})
    rows = []
    for object_id, group in frame.groupby("object_id", sort=True):
        row = {"object_id": object_id, "sampled": len(group), "kept": int((group["reason"] == "").sum())}
        row.update({r: int((group["reason"] == r).sum()) for r in DROP_REASONS})
        rows.append(row)
    return pd.DataFrame(rows, columns=columns)
