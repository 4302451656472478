"""One round of the data loop (Dex1B): sample with the last model, refine, validate, keep what is new, retrain.

Round r >= 1 starts from round r-1's model (round 0's is the pipeline's ``results/model/cvae.pt``)
and round r-1's grasp set (round 0's: the lift-successful grasps of training objects that model
was trained on). Per shard it samples ``loop.grasps_per_object`` grasps on every stable training
object, those without any grasp yet included, with the loop's associated points (``loop.anchor_rule``:
``round_sample_settings``); the pipeline's post-optimization refines them; the equal energy
filter (``evaluation.filter_energy`` at ``curate.thresholds``), the lift test and (``loop.six_directions``)
the six-direction test validate them, on each object's table in tabletop mode. ``merge_round`` then
keeps each validated grasp that is a new distinct grasp (``evaluation.diversity``: not the same grasp
as one of the set nor as an earlier pick of the round) and the next model trains on the merged set,
warm-started. Every candidate that is not kept carries one ``drop_reason`` (``DROP_REASONS``).

The same sampling, refinement and validation run each round's model on the held-out objects with a
small cap (``loop.heldout_grasps_per_object``): the loop table's held-out curve over rounds.
"""

from __future__ import annotations

import dataclasses
import logging
import os

import numpy as np
import pandas as pd

from dexlite_pipeline.config import json_ready
from dexlite_pipeline.evaluation.diversity import DiversityConfig, distinct_grasp_labels, first_of_each_cluster
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store
from dexlite_pipeline.loop.config import LoopConfig

log = logging.getLogger(__name__)

TRAIN, HELDOUT = "train", "heldout"  # the object splits a round samples on (``PARTS``)
PARTS = (TRAIN, HELDOUT)
LOOP_METHOD = "cvae_loop"  # method label of the grasps a round samples on training objects
# Why a sampled grasp is not added to the set, in the order the checks run ("" = kept).
NOT_OPTIMIZED = "not_optimized"  # the post-optimization could not run on it (invalid pose, no asset or resting pose)
ENERGY_FILTER = "energy_filter"  # above a threshold of the equal energy filter
LIFT_TEST = "lift_test"  # dropped or not lifted in the lift test
SIX_DIRECTIONS = "six_directions"  # held in the lift test, moved in the six-direction test
DUPLICATE = "duplicate"  # the same grasp (diversity definition) as one already in the set or picked earlier this round
DROP_REASONS = (NOT_OPTIMIZED, ENERGY_FILTER, LIFT_TEST, SIX_DIRECTIONS, DUPLICATE)
SET_ARRAYS = ("hand_pose", "object_id", "scale", "lift_success", "contact_index", "round")  # the arrays of a round's grasp set


def round_seed(seed: int, round_number: int, shard: int = 0, part: str = TRAIN) -> int:
    """The random seed of one round's step on one shard: a different stream per round, shard and part, none of
    them the global ``seed`` itself (round 0's training and sampling use that)."""
    return int(seed) * 1_000_003 + 104_729 * (int(round_number) + 1) + 7919 * int(shard) + (0 if part == TRAIN else 613)


def round_training_config(train, loop: LoopConfig):
    """The ``train`` section for one round's training: ``loop.train_steps`` steps fine-tuning the previous round's
    model at ``train.learning_rate * loop.fine_tune_learning_rate_factor``, constant, with no learning-rate warm-up
    and the energy terms at full weight from the first step (the model is trained already)."""
    return dataclasses.replace(
        train, max_steps=loop.train_steps, learning_rate=train.learning_rate * loop.fine_tune_learning_rate_factor,
        lr_schedule="constant", lr_warmup_steps=0, energy_warmup_fraction=0.0,
    )  # fmt: skip


def process_cpu_seconds() -> float:
    """CPU seconds (user + system) this process and its finished children have used so far: a job's own cost."""
    times = os.times()
    return float(times.user + times.system + times.children_user + times.children_system)


def initial_set(lift_paths: list[str], objects_dirs: list[str]) -> GraspSet:
    """Round 0's grasp set: the lift-successful grasps of prepared training objects in the lift shards
    (what the first model trains on), with their contacts (-1 for imported grasps) and ``round`` 0."""
    from dexlite_pipeline.model.trainer import read_lift_shards
    from dexlite_pipeline.objects.assets import available_object_ids, object_splits

    lifted = read_lift_shards(lift_paths)
    if not len(lifted):
        return _grasp_set({}, 0)
    train_ids = {oid for oid, split in object_splits(objects_dirs).items() if split == TRAIN} & available_object_ids(objects_dirs)
    keep = np.asarray(lifted.arrays["lift_success"], bool) & np.isin(lifted.object_id.astype(str), sorted(train_ids))
    keep &= np.isfinite(lifted.hand_pose).all(axis=1)
    return _grasp_set({k: lifted.arrays[k][keep] for k in ("hand_pose", "object_id", "scale", "contact_index")}, 0)


def _grasp_set(arrays: dict, round_number: int) -> GraspSet:
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


def round_objects(objects_dirs: list[str], stability_path: str, shard: int, shard_count: int, part: str) -> tuple[list[str], dict[str, str]]:
    """The shard's stable prepared objects of split ``part`` (dealt as in the other grasp stages), and those left out with why."""
    from dexlite_pipeline.objects.assets import available_object_ids, object_splits
    from dexlite_pipeline.objects.stability import stable_object_ids
    from dexlite_pipeline.sharding import shard_objects

    if part not in PARTS:
        raise ValueError(f"part {part!r} is not one of {', '.join(PARTS)}")
    splits = object_splits(objects_dirs)
    ids = shard_objects(sorted(stable_object_ids(stability_path) & set(splits)), shard, shard_count)
    available = available_object_ids(objects_dirs)
    mine = [oid for oid in ids if splits[oid] == part]
    return [oid for oid in mine if oid in available], {oid: "no prepared asset" for oid in mine if oid not in available}


def round_post_optimize_config(post_optimize, loop: LoopConfig, part: str):
    """The ``post_optimize`` section a round's refinement of part ``part`` runs: without the random-start baseline
    (the evaluation's), and on the training part for ``loop.post_iterations`` annealed steps when set (the same
    schedule's constants, run longer); the held-out check refines as the evaluation does, so it measures the same."""
    post_optimize = dataclasses.replace(post_optimize, random_baseline=False)
    if part == TRAIN and loop.post_iterations > 0:
        post_optimize = dataclasses.replace(post_optimize, annealing=dataclasses.replace(post_optimize.annealing, iterations=loop.post_iterations))
    return post_optimize


def round_sample_settings(sample, loop: LoopConfig, part: str):
    """(sample settings, grasps per object, method label) of a round's part: ``train`` samples ``loop.grasps_per_object``
    per object with the loop's own associated points (``loop.anchor_rule``, ``loop.match_candidates``), labelled
    ``LOOP_METHOD``; ``heldout`` ``loop.heldout_grasps_per_object`` by the ``sample`` section's rules as they are,
    labelled as the evaluation's pure synthesis (``cvae_raw``), so the held-out check measures what the evaluation does."""
    from dexlite_pipeline.model.methods import SYNTHESIS

    if part == TRAIN:
        settings = dataclasses.replace(sample, anchor_rule=loop.anchor_rule, match_candidates=loop.match_candidates)
        return settings, loop.grasps_per_object, LOOP_METHOD
    return sample, loop.heldout_grasps_per_object, SYNTHESIS


def sample_round(
    model_path: str, objects_dirs: list[str], stability_path: str, shard: int, shard_count: int, part: str, round_number: int,
    loop: LoopConfig, sample, device, seed: int,
) -> tuple[GraspSet, dict]:
    """Grasps of one shard's objects of split ``part`` from the model at ``model_path`` (``sample``: the ``SampleConfig``).

    What each part samples: ``round_sample_settings``. Returns the grasps (hand_pose, object_id, scale, method) and
    the store attributes.
    """
    import torch

    from dexlite_pipeline.model.checkpoint import cloud_reading, load_checkpoint
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.sampling import SampledRows, synthesis_rows
    from dexlite_pipeline.objects.assets import load_asset

    model, checkpoint = load_checkpoint(model_path, device)
    points, fixed_clouds = cloud_reading(checkpoint, sample.points_per_cloud)
    object_ids, skipped = round_objects(objects_dirs, stability_path, shard, shard_count, part)
    settings, count, label = round_sample_settings(sample, loop, part)
    generator = torch.Generator().manual_seed(round_seed(seed, round_number, shard, part))
    if object_ids and count > 0:
        clouds = ObjectClouds([load_asset(objects_dirs, oid) for oid in object_ids], model.codes_mu.device)
        rows = synthesis_rows(model, clouds, object_ids, settings, points, generator, fixed_clouds, label, count)
    else:
        rows = SampledRows.concatenate([], model.codes_mu.device)
    arrays = {
        "hand_pose": rows.hand_pose.cpu().numpy(),
        "object_id": np.asarray(rows.object_id, dtype=object),
        "scale": rows.scale,
        "method": np.asarray(rows.method, dtype=object),
    }
    attrs = {
        "stage": "loop_sample", "round": int(round_number), "part": part, "shard": f"{shard:03d}", "model": str(model_path),
        "model_steps": checkpoint.get("steps"), "config": {"seed": seed, "loop": json_ready(loop), "sample": json_ready(settings)},
        "skipped_objects": skipped,
    }  # fmt: skip
    log.info("round %d %s shard %03d: %d grasps on %d objects from %s", round_number, part, shard, len(rows.method), len(object_ids), model_path)
    return GraspSet(arrays, {}), attrs


def validate_round(
    post_path: str, objects_dirs: list[str], thresholds, energy_weights, lift, six_directions: bool, threads: int = 1,
    support_planes=None, device: str = "cpu", simulate_all: bool = False,
) -> GraspSet:
    """The refined grasps of ``post_path`` with the checks a new grasp must pass, and ``drop_reason`` per grasp.

    In order: refined at all (``NOT_OPTIMIZED``), below every threshold of ``thresholds`` (``EnergyThresholds``) with
    the equal filter's contacts (``ENERGY_FILTER``; E_pen and the penetration depth the refined ones), the lift test (``LIFT_TEST``) and, with
    ``six_directions``, the six-direction test (``SIX_DIRECTIONS``); ``lift`` is the ``LiftConfig``, ``support_planes``
    the tables (tabletop mode). Only grasps that passed the checks before are simulated (the others keep NaN results),
    or with ``simulate_all`` every refined grasp (the held-out check: success per attempt, as the evaluation counts it).
    """
    from dexlite_pipeline.evaluation.filter_energy import FILTER_CONTACTS, FILTER_ENERGIES, filter_energy_arrays
    from dexlite_pipeline.evaluation.metrics import filter_flags
    from dexlite_pipeline.sim.lift import run_lift_tests

    post = read_grasp_store(post_path)
    n = len(post)
    arrays = dict(post.arrays)
    reason = np.full(n, "", dtype=object)
    failure = np.asarray(arrays.get("failure_reason", np.full(n, "", dtype=object))).astype(str)
    optimized = (failure == "") & np.isfinite(post.hand_pose).all(axis=1)
    reason[~optimized] = NOT_OPTIMIZED
    rows = np.flatnonzero(optimized)
    found = filter_energy_arrays(post.select(rows), objects_dirs, energy_weights, device)
    arrays[FILTER_CONTACTS] = np.full((n, 4), -1, np.int64)
    for name in FILTER_ENERGIES:
        arrays[name] = np.full(n, np.nan, np.float32)
    for name, values in found.items():
        arrays[name][rows] = values
    # E_pen and the judged depth are the refined pose's; absent when no row was refined
    refined = {name: np.asarray(arrays.get(name, np.full(n, np.nan)), np.float64) for name in ("E_pen", "penetration_mm")}
    passing = filter_flags({"hand_pose": post.hand_pose, **arrays, **refined}, thresholds.limits())
    reason[(reason == "") & ~passing] = ENERGY_FILTER
    rows = np.flatnonzero(optimized if simulate_all else reason == "")
    lift = dataclasses.replace(lift, six_directions=six_directions)
    lifted = run_lift_tests(post.select(rows), objects_dirs, lift, threads, support_planes)
    for name, values in lifted.items():
        arrays["lift_failure_reason" if name == "failure_reason" else name] = _scattered(values, rows, n)
    reason[(reason == "") & ~arrays["lift_success"].astype(bool)] = LIFT_TEST
    if six_directions:
        reason[(reason == "") & ~arrays["six_dir_success"].astype(bool)] = SIX_DIRECTIONS
    arrays["drop_reason"] = reason
    attrs = {**post.attrs, "stage": "loop_validate", "lift_config": lift.as_dict(), "thresholds": thresholds.limits()}
    return GraspSet(arrays, attrs)


def _scattered(values: np.ndarray, rows: np.ndarray, n: int) -> np.ndarray:
    """(n, ...) ``values`` placed at ``rows``; elsewhere "" (strings), False (flags) or NaN (numbers)."""
    values = np.asarray(values)
    if values.dtype == object:
        full = np.full((n, *values.shape[1:]), "", dtype=object)
    elif values.dtype == bool:
        full = np.zeros((n, *values.shape[1:]), dtype=bool)
    else:
        full = np.full((n, *values.shape[1:]), np.nan, dtype=np.float64 if values.dtype.kind in "iu" else values.dtype)
    full[rows] = values
    return full


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
    known_pose = np.asarray(known_pose, np.float64).reshape(-1, 28)
    new_pose = np.asarray(new_pose, np.float64).reshape(-1, 28)
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


def merge_round(previous: GraspSet, validated: list[GraspSet], diversity: DiversityConfig, round_number: int) -> tuple[GraspSet, GraspSet]:
    """Round ``round_number``'s set and its candidates: ``previous`` plus the validated grasps that are new distinct grasps.

    ``validated``: the round's ``validate_round`` shards. Candidates that passed every check are taken best first
    (lowest E_post; ties in shard and row order) and kept by ``new_distinct_grasps``; the others get ``DUPLICATE``.
    Returns the merged set (``SET_ARRAYS``; the kept grasps with ``round`` = ``round_number``) and every candidate
    (object_id, scale, E_post, drop_reason) in shard and row order.
    """
    stores = [v for v in validated if len(v)]
    candidates = GraspSet.concatenate_common(stores)[0] if stores else None
    if candidates is None or not len(candidates):
        return GraspSet(dict(previous.arrays), {}), _grasp_set({}, round_number)
    reason = np.asarray(candidates.arrays["drop_reason"], dtype=object).copy()
    energy = np.asarray(candidates.arrays.get("E_post", np.zeros(len(candidates))), np.float64)
    passed = np.flatnonzero(reason == "")
    order = passed[np.argsort(np.where(np.isfinite(energy[passed]), energy[passed], np.inf), kind="stable")]
    kept = new_distinct_grasps(previous.hand_pose, grasp_groups(previous), candidates.hand_pose[order], grasp_groups(candidates.select(order)), diversity)
    reason[order[~kept]] = DUPLICATE
    new_rows = np.sort(order[kept])
    contacts = np.asarray(candidates.arrays.get("contact_index", np.full((len(candidates), 4), -1)), np.int64)
    added = _grasp_set({"hand_pose": candidates.hand_pose[new_rows], "object_id": candidates.object_id[new_rows],
                        "scale": candidates.scale[new_rows], "contact_index": contacts[new_rows]}, round_number)  # fmt: skip
    merged = GraspSet.concatenate([GraspSet({k: previous.arrays[k] for k in SET_ARRAYS}), added], attrs={})
    table = GraspSet({"hand_pose": candidates.hand_pose, "object_id": candidates.object_id, "scale": candidates.scale,
                      "E_post": energy, "drop_reason": reason}, {})  # fmt: skip
    log.info("round %d: %d candidates, %d kept (%s)", round_number, len(candidates), len(new_rows),
             ", ".join(f"{r} {int((reason == r).sum())}" for r in DROP_REASONS))
    return merged, table


def merge_round_stores(previous_path: str, validated_paths: list[str], diversity: DiversityConfig, round_number: int) -> tuple[GraspSet, dict]:
    """``merge_round`` of the stores at the paths: the merged set, its candidates as arrays ``candidate_*`` in the attributes' stead."""
    merged, candidates = merge_round(read_grasp_store(previous_path), [read_grasp_store(p) for p in validated_paths], diversity, round_number)
    counts = candidate_counts(candidates)
    attrs = {"stage": "loop_merge", "round": int(round_number), "config": {"diversity": json_ready(diversity)},
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


def stores_cpu_seconds(paths: list[str]) -> float:
    """The CPU seconds the jobs that wrote the stores at ``paths`` recorded (attribute ``cpu_seconds``; 0 where absent)."""
    return float(sum(float(read_grasp_store(p).attrs.get("cpu_seconds") or 0.0) for p in paths))


def round_summary(
    round_number: int, set_path: str, heldout_paths: list[str], cost_paths: list[str], heldout_cost_paths: list[str], model_path: str | None,
    objects_dirs: list[str], stability_path: str, diversity: DiversityConfig,
) -> tuple[pd.DataFrame, dict]:
    """The round's table per training object and its one row of the loop table.

    Per stable training object: grasps and distinct grasps in the round's set (``set_path``), and the round's
    candidates sampled, kept and dropped per reason (none in round 0). The row: those per object (means over the
    training objects), the CPU seconds of the round's jobs (``cost_paths``' stores and the model's training;
    ``model_path`` None in round 0, whose set the pipeline's stages made), and the held-out check of the round's
    model (``heldout_paths``: validated held-out grasps): attempts, lift and six-direction success per attempt,
    distinct held grasps per held-out object, its CPU seconds (``heldout_cost_paths``).
    """
    from dexlite_pipeline.evaluation.metrics import per_object_diversity

    grasps = read_grasp_store(set_path)
    object_ids = round_objects(objects_dirs, stability_path, 0, 1, TRAIN)[0]
    counts = per_object_diversity(grasps.arrays, np.ones(len(grasps), bool), diversity) if len(grasps) else {}
    candidates = pd.DataFrame(grasps.attrs.get("candidates") or [], columns=["object_id", "sampled", "kept", *DROP_REASONS]).set_index("object_id")
    rows = []
    for object_id in sorted(set(object_ids) | set(counts)):
        row = {"object_id": object_id, "grasps": counts.get(object_id, {}).get("held", 0), "distinct_grasps": counts.get(object_id, {}).get("distinct", 0)}
        row.update({k: int(candidates.loc[object_id, k]) if object_id in candidates.index else 0 for k in ("sampled", "kept", *DROP_REASONS)})
        rows.append(row)
    table = pd.DataFrame(rows, columns=["object_id", "grasps", "distinct_grasps", "sampled", "kept", *DROP_REASONS])
    cpu = stores_cpu_seconds(cost_paths)
    model_steps = None
    if model_path is not None:
        from dexlite_pipeline.model.checkpoint import load_checkpoint

        checkpoint = load_checkpoint(model_path)[1]
        cpu += float(checkpoint.get("cpu_seconds") or 0.0)
        model_steps = checkpoint.get("steps")
    summary = {
        "round": int(round_number),
        "training_objects": len(table),
        "objects_without_grasps": int((table["grasps"] == 0).sum()),
        "grasps": int(table["grasps"].sum()),
        "grasps_per_object": float(table["grasps"].mean()) if len(table) else float("nan"),
        "distinct_per_object": float(table["distinct_grasps"].mean()) if len(table) else float("nan"),
        "distinct_min": int(table["distinct_grasps"].min()) if len(table) else 0,
        **{k: int(table[k].sum()) for k in ("sampled", "kept", *DROP_REASONS)},
        "model_steps": model_steps,
        "cpu_seconds": cpu if round_number > 0 else float("nan"),
        **heldout_check([read_grasp_store(p) for p in heldout_paths], diversity),
        "heldout_cpu_seconds": stores_cpu_seconds(heldout_cost_paths),
    }
    return table, summary


def heldout_check(validated: list[GraspSet], diversity: DiversityConfig) -> dict:
    """Attempts, lift and six-direction success per attempt (a grasp not refined counts as a failure) and distinct
    held grasps per held-out object (objects with attempts, one without a held grasp counting 0) of a held-out check."""
    from dexlite_pipeline.evaluation.metrics import per_object_diversity

    stores = [v for v in validated if len(v)]
    if not stores:
        return {"heldout_objects": 0, "heldout_attempts": 0, "heldout_lift_success": float("nan"),
                "heldout_six_dir_success": float("nan"), "heldout_distinct_per_object": float("nan")}  # fmt: skip
    grasps = GraspSet.concatenate_common(stores)[0]
    held = np.asarray(grasps.arrays["lift_success"], bool)
    six = np.asarray(grasps.arrays["six_dir_success"], bool) if "six_dir_success" in grasps.arrays else np.zeros(len(grasps), bool)
    per_object = per_object_diversity(grasps.arrays, held, diversity)
    return {
        "heldout_objects": len(per_object),
        "heldout_attempts": len(grasps),
        "heldout_lift_success": float(held.mean()),
        "heldout_six_dir_success": float(six.mean()),
        "heldout_distinct_per_object": float(np.mean([v["distinct"] for v in per_object.values()])),
    }


LOOP_TABLE_COLUMNS = (
    "round", "training_objects", "objects_without_grasps", "grasps", "grasps_per_object", "distinct_per_object", "distinct_min",
    "sampled", "kept", *DROP_REASONS, "model_steps", "cpu_seconds", "heldout_objects", "heldout_attempts", "heldout_lift_success",
    "heldout_six_dir_success", "heldout_distinct_per_object", "heldout_cpu_seconds",
)  # fmt: skip


def loop_table(rows: list[dict]) -> pd.DataFrame:
    """The loop table (results/loop.csv): one row per round (``round_summary``), in round order."""
    return pd.DataFrame(sorted(rows, key=lambda r: r["round"]), columns=list(LOOP_TABLE_COLUMNS))
