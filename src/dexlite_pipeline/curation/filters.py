"""Curation: which optimized / imported grasps become training data for the lift test and the CVAE.

A grasp is kept when its object is prepared (status ok), in the train split and stable on
a table; its pose is finite and its energies exist; it meets the energy thresholds
(DexGraspNet's E_fc < 0.3, E_dis < 5 mm, E_pen < 1 mm by default, and the start depth cap;
``optimized_thresholded_terms`` says which apply); with ``force_closure``
on, the contacts it actually makes are in force closure with friction (Ferrari–Canny ε
above ``force_closure_min_epsilon``, see below); it is not a near-duplicate of a better
grasp; and its object's cap is not yet full. Every other grasp gets the first reason
that applies, in ``DROP_REASONS`` order, so the per-object counts of the summary add up
to the grasps read.

Near-duplicates: two grasps of the same object at the same scale whose palm positions
differ by less than ``duplicate_translation_m``, palm orientations by less than
``duplicate_rotation_deg`` (geodesic angle) and every joint by less than
``duplicate_joint_rad``. All three must hold: grasps with the same palm pose but other
finger configurations (or the reverse) are different grasps. Grasps are ranked by
``quality_score`` (the three thresholded energies as fractions of their thresholds,
summed; lower is better); walking down the ranking, a grasp is dropped when it is a
near-duplicate of one already kept, and the cap keeps the best-ranked survivors.

Imported DexGraspNet grasps (``origin`` 'dexgraspnet') are held only to the thresholds of
``imported_thresholded_terms`` (default E_dis). Their makers filtered them with their own
contact points, which the dataset does not store, and a one-way penetration sum, so our
E_fc and E_pen of real grasps are far above the thresholds even for grasps that hold,
while E_dis (scored at the four pads nearest the surface, the least any contact choice
gives) stays a fair test. All their energies are still computed, stored and used to rank
them for the near-duplicate and cap steps.

Force closure of the actual contacts (``dexlite_pipeline.curation.force_closure``): every hand link
within ``force_closure_contact_distance_m`` of the object is a contact with a friction
cone (``force_closure_friction``); ε is the largest wrench, in every direction, they
resist per newton of total normal force. Why: E_fc is scored on four contact candidates
that optimization from scratch picks after the fact, with unit normals and no friction, and its
torque term (contact points in metres) is about 1/scale² weaker than with torques over
the object's radius, so E_fc < 0.3 says little about how the hand presses. The contact
distance is the energy thresholds' own scale (E_dis < 5 mm over four contacts is 1.25 mm
each). The check applies to imported grasps too: it uses no stored contacts. The
measurements behind these choices are in docs/results.md ("Curation").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd
import torch

from dexlite_pipeline.curation.config import IMPORTED_ORIGIN, THRESHOLDED_TERMS, CurateConfig
from dexlite_pipeline.curation.force_closure import ForceClosureResult
from dexlite_pipeline.hand.model import JOINTS, ROTATION, TRANSLATION
from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix
from dexlite_pipeline.io.grasp_store import GraspSet, invalid_grasp_reasons

DROP_REASONS = (
    "object_not_ok",  # not in any object catalog, or rejected there
    "not_train",  # held out for evaluation
    "no_stability_result",  # the stability filter did not test the object
    "unstable",  # the object does not stand stably on a table
    "invalid_grasp",  # non-finite pose or scale, or energies could not be computed
    "e_fc",  # E_fc >= max_e_fc
    "e_dis",  # E_dis >= max_e_dis_m
    "e_pen",  # E_pen >= max_e_pen_m
    "penetration_mm",  # penetration depth (the lift test's start measure) > max_penetration_m
    "force_closure_unknown",  # its force closure could not be computed (e.g. unreadable object asset; reason in force_closure_failure_reason)
    "force_closure",  # the contacts it makes are not in force closure with a margin (epsilon <= force_closure_min_epsilon)
    "duplicate",  # near-duplicate of a better grasp of the same object and scale
    "cap",  # beyond max_grasps_per_object
)
# Tabletop mode (scene.table) adds one reason after "unstable"; floating curation keeps exactly the list above.
BELOW_TABLE = "below_table"  # a hand point below the object's table in its resting pose (tabletop mode)
TABLETOP_DROP_REASONS = (*DROP_REASONS[:4], BELOW_TABLE, *DROP_REASONS[4:])


@dataclass(frozen=True)
class ObjectFacts:
    """Per object: catalog status and split, stability verdict (None: not tested)."""

    status: dict[str, str]
    split: dict[str, str]
    stable: dict[str, bool]

    @staticmethod
    def from_tables(catalogs: list[pd.DataFrame], stability: list[pd.DataFrame]) -> "ObjectFacts":
        """Merge object catalogs and stability tables (the first table that names an object wins)."""
        status, split, stable = {}, {}, {}
        for catalog in catalogs:
            for row in catalog.itertuples(index=False):
                oid = str(row.object_id)
                status.setdefault(oid, str(row.status))
                split.setdefault(oid, str(getattr(row, "split", "")))
        for table in stability:
            for oid, verdict in zip(table["object_id"].astype(str), table["stable"].astype(bool)):
                stable.setdefault(oid, bool(verdict))
        return ObjectFacts(status, split, stable)


def object_reasons(grasps: GraspSet, facts: ObjectFacts) -> np.ndarray:
    """Per grasp, the first object-level and validity reason that drops it ('' if none)."""
    ids = [str(o) for o in grasps.object_id]
    reasons = np.full(len(ids), "", dtype=object)
    checks = (
        ("object_not_ok", lambda oid: facts.status.get(oid) != "ok"),
        ("not_train", lambda oid: facts.split.get(oid) != "train"),
        ("no_stability_result", lambda oid: oid not in facts.stable),
        ("unstable", lambda oid: not facts.stable.get(oid, False)),
    )
    for reason, fails in checks:
        failing_ids = {oid for oid in set(ids) if fails(oid)}
        hit = (reasons == "") & np.fromiter((oid in failing_ids for oid in ids), bool, len(ids))
        reasons[hit] = reason
    reasons[(reasons == "") & (invalid_grasp_reasons(grasps) != "")] = "invalid_grasp"
    return reasons


def threshold_reasons(grasps: GraspSet, config: CurateConfig) -> np.ndarray:
    """Per grasp, 'invalid_grasp' for missing/NaN energies, else the first threshold it fails ('' if none).

    Imported grasps are held only to the thresholds of ``config.imported_thresholded_terms``, the others to those of
    ``config.optimized_thresholded_terms``.
    """
    n = len(grasps)
    reasons = np.full(n, "", dtype=object)
    missing = [t for t in THRESHOLDED_TERMS if t not in grasps.arrays]
    if missing:
        raise ValueError(f"grasps lack the energy arrays {', '.join(missing)} needed for curation")
    values = {t: np.asarray(grasps.arrays[t], np.float64) for t in THRESHOLDED_TERMS}
    reasons[~np.all([np.isfinite(v) for v in values.values()], axis=0)] = "invalid_grasp"
    imported = np.asarray(grasps.arrays.get("origin", np.full(n, "", dtype=object)) == IMPORTED_ORIGIN, bool)
    limits = {name: (name.lower(), limit) for name, limit in config.thresholds.limits().items()}
    for term, (reason, limit) in limits.items():
        checked = np.where(imported, term in config.imported_thresholded_terms, term in config.optimized_thresholded_terms)
        within = values[term] <= limit if term == "penetration_mm" else values[term] < limit
        reasons[checked & (reasons == "") & ~within] = reason
    return reasons


def quality_score(grasps: GraspSet, config: CurateConfig) -> np.ndarray:
    """E_fc/max_e_fc + E_dis/max_e_dis_m + E_pen/max_e_pen_m over ``curate.thresholds`` (lower is better); < 3 for every kept grasp."""
    a = grasps.arrays
    return (
        np.asarray(a["E_fc"], np.float64) / config.thresholds.max_e_fc
        + np.asarray(a["E_dis"], np.float64) / config.thresholds.max_e_dis_m
        + np.asarray(a["E_pen"], np.float64) / config.thresholds.max_e_pen_m
    )


def near_duplicates(hand_pose: np.ndarray, order: np.ndarray, config: CurateConfig) -> np.ndarray:
    """Boolean (N,): grasps (of one object and scale) that near-duplicate a better one kept before them.

    ``order`` ranks the grasps best first. O(N²) time in vectorized rows, O(N) memory.
    """
    pose = torch.as_tensor(np.asarray(hand_pose, np.float64)[order])
    translation = pose[:, TRANSLATION]
    rotation = euler_xyz_to_matrix(pose[:, ROTATION]).reshape(-1, 9)
    joints = pose[:, JOINTS.start:]  # the hand's joints: columns 6 to 28 for the Shadow Hand, 6 + J for a hand from its MJCF
    # trace(Ri^T Rj) = vec(Ri)·vec(Rj); angle < a  <=>  trace > 1 + 2 cos a
    min_trace = 1.0 + 2.0 * math.cos(math.radians(config.duplicate_rotation_deg))
    n = pose.shape[0]
    removed = torch.zeros(n, dtype=torch.bool)
    for i in range(n):
        if removed[i]:
            continue
        rest = slice(i + 1, n)
        close = (
            ((translation[rest] - translation[i]).norm(dim=1) < config.duplicate_translation_m)
            & ((rotation[rest] @ rotation[i]) > min_trace)
            & ((joints[rest] - joints[i]).abs().amax(dim=1) < config.duplicate_joint_rad)
        )
        removed[rest] |= close
    duplicate = np.zeros(n, bool)
    duplicate[order] = removed.numpy()
    return duplicate


def curate_grasps(
    grasps: GraspSet, facts: ObjectFacts, config: CurateConfig, force_closure_evaluator: Callable[[GraspSet], ForceClosureResult] | None = None,
    table_depth_m: np.ndarray | None = None,
) -> np.ndarray:
    """Per grasp, '' if kept, else its drop reason (one of ``DROP_REASONS``; ``TABLETOP_DROP_REASONS`` on a table).

    ``table_depth_m`` (tabletop mode): per grasp the deepest hand point below its object's table
    (``energy.table_clearance.grasp_table_depths``); grasps deeper than ``tabletop.TABLE_TOLERANCE_M`` (or with
    no table) are dropped as ``below_table`` after the object-level checks.

    With ``config.force_closure``, ``force_closure_evaluator`` is called once, on the
    grasps that meet the energy thresholds, and its results are added to ``grasps`` as the
    arrays ``force_closure_epsilon`` (NaN where not evaluated) and
    ``force_closure_failure_reason`` (why ε could not be computed, '' elsewhere).
    """
    reasons = object_reasons(grasps, facts)
    if table_depth_m is not None:
        from dexlite_pipeline.tabletop import TABLE_TOLERANCE_M

        reasons[(reasons == "") & ~(np.asarray(table_depth_m) <= TABLE_TOLERANCE_M)] = BELOW_TABLE
    open_rows = reasons == ""
    if open_rows.any():
        reasons[open_rows] = threshold_reasons(grasps.select(open_rows), config)
    if config.force_closure:
        if force_closure_evaluator is None:
            raise ValueError("config.curate.force_closure is on but no force-closure evaluator was given")
        evaluated = reasons == ""
        epsilon = np.full(len(grasps), np.nan)
        failure_reason = np.full(len(grasps), "", dtype=object)
        if evaluated.any():
            result = force_closure_evaluator(grasps.select(evaluated))
            epsilon[evaluated] = result.epsilon
            failure_reason[evaluated] = result.failure_reason
        grasps.arrays["force_closure_epsilon"] = epsilon.astype(np.float32)
        grasps.arrays["force_closure_failure_reason"] = failure_reason
        reasons[evaluated & (failure_reason != "")] = "force_closure_unknown"
        reasons[evaluated & (reasons == "") & ~(epsilon > config.force_closure_min_epsilon)] = "force_closure"
    passing = np.nonzero(reasons == "")[0]
    if len(passing) == 0:
        return reasons
    score = quality_score(grasps.select(passing), config)
    object_ids = np.asarray([str(o) for o in grasps.object_id[passing]])
    scales = np.asarray(grasps.scale[passing], np.float32)
    for object_id in np.unique(object_ids):
        in_object = object_ids == object_id
        for scale in np.unique(scales[in_object]):
            group = np.nonzero(in_object & (scales == scale))[0]
            order = np.argsort(score[group], kind="stable")
            duplicate = near_duplicates(grasps.hand_pose[passing[group]], order, config)
            reasons[passing[group[duplicate]]] = "duplicate"
        if config.max_grasps_per_object:
            survivors = passing[in_object][reasons[passing[in_object]] == ""]
            ranked = survivors[np.argsort(score[np.searchsorted(passing, survivors)], kind="stable")]
            reasons[ranked[config.max_grasps_per_object :]] = "cap"
    return reasons


def summarize(grasps: GraspSet, reasons: np.ndarray, facts: ObjectFacts, drop_reasons: tuple[str, ...] = DROP_REASONS) -> pd.DataFrame:
    """Per object and origin: split, stability, grasps read, kept, and dropped per reason (``drop_reasons``)."""
    origin = grasps.arrays.get("origin", np.full(len(grasps), "", dtype=object))
    frame = pd.DataFrame({"object_id": [str(o) for o in grasps.object_id], "origin": list(origin), "reason": list(reasons)})
    columns = ["object_id", "origin", "split", "stable", "n_input", "n_kept", *(f"dropped_{r}" for r in drop_reasons)]
    if frame.empty:
        return pd.DataFrame(columns=columns)
    counts = pd.crosstab([frame["object_id"], frame["origin"]], frame["reason"])
    counts = counts.reindex(columns=["", *drop_reasons], fill_value=0)
    table = pd.DataFrame(
        {
            "n_input": counts.sum(axis=1),
            "n_kept": counts[""],
            **{f"dropped_{r}": counts[r] for r in drop_reasons},
        }
    ).reset_index()
    table["split"] = [facts.split.get(o, "") for o in table["object_id"]]
    table["stable"] = [facts.stable.get(o) for o in table["object_id"]]
    return table[columns].sort_values(["object_id", "origin"], ignore_index=True)


def merge_summaries(tables: list[pd.DataFrame]) -> pd.DataFrame:
    """Concatenate per-shard summaries (shards hold disjoint objects) into one table."""
    if not tables:
        raise ValueError("no curation summaries to merge")
    merged = pd.concat(tables, ignore_index=True)
    duplicated = merged.duplicated(["object_id", "origin"])
    if duplicated.any():
        first = merged.loc[duplicated, "object_id"].iloc[0]
        raise ValueError(f"object {first!r} appears in more than one curation summary; shards must be disjoint")
    return merged.sort_values(["object_id", "origin"], ignore_index=True)
