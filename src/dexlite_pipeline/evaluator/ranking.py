"""Ranking the model's samples by the learned evaluator (stage ``sample_grasps`` with ``evaluator.enabled``).

For each held-out object the evaluation simulates ``evaluate.grasps_per_object`` of the pure syntheses (at most
``sample.synthesis_grasps_per_object``); the model draws ``evaluator.pool_factor`` times that many, the evaluator
scores each sampled pose (the probability it holds once post-optimized and lift-tested, on the object's table in
tabletop mode), and the best-scored *distinct* ones are kept (``evaluation.ranking.rank_distinct``, topped up with
the next best when fewer are distinct): rows ``cvae_ranked``, post-optimized and simulated like ``cvae_raw``'s, as
many per object as the evaluation simulates of those. Each simulated ranked grasp is so the best of ``pool_factor``
candidates, as ``dexlite grasp`` keeps ``--n`` of ``pool_factor`` x ``--n``.
The pool has its own random stream, so the unranked rows are the same with ranking on or off. The unranked pure
syntheses get the evaluator's score too (``evaluator_score``): the evaluation measures the score's ROC AUC on
held-out objects from them.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from dexlite_pipeline.io.grasp_store import GRASP_TYPE, GraspSet

log = logging.getLogger(__name__)

RANKED_METHOD = "cvae_ranked"  # method label of the ranked pure syntheses
SCORE = "evaluator_score"  # per sampled row: the evaluator's probability of "held" (NaN where not scored)
KEPT_FRACTION = "evaluator_kept_fraction"  # per sampled row: the share of its pool ranking keeps (1 / pool_factor)
RANK = "evaluator_rank"  # per ranked row: its place in its object's ranking (0 = best; distinct grasps first), -1 elsewhere


def support_rows(planes, object_ids, scale) -> np.ndarray | None:
    """(N, 4) each grasp's table (``model.evaluator.SUPPORT_COLUMNS``) in tabletop mode, None floating."""
    if planes is None:
        return None
    from dexlite_pipeline.tabletop import support_arrays

    arrays = support_arrays(planes, object_ids, scale)
    return np.concatenate([arrays["support_normal"], arrays["support_offset_m"].reshape(-1, 1)], axis=1).astype(np.float32)


def best_distinct(scores: np.ndarray, poses: np.ndarray, object_ids: np.ndarray, keep: int, diversity) -> tuple[np.ndarray, np.ndarray]:
    """(rows kept, each one's place in its object's ranking): at most ``keep`` best-scored distinct grasps per object
    (``DiversityConfig``'s rule), topped up with the next best; rows in the input's order, places 0 = best."""
    from dexlite_pipeline.evaluation.ranking import rank_distinct

    chosen = rank_distinct(scores, poses, object_ids, keep, diversity.distinct_translation_m, diversity.distinct_rotation_deg, fill=True)
    place = np.empty(len(chosen), np.int32)  # chosen is in ranking order
    for object_id in set(object_ids[chosen].tolist()):
        mine = np.flatnonzero(object_ids[chosen] == object_id)
        place[mine] = np.arange(len(mine))
    order = np.argsort(chosen, kind="stable")
    return chosen[order], place[order]


def rank_candidates(
    candidates: GraspSet, evaluator_path: str, objects_dirs: list[str], stability_path: str, keep: int, diversity, table: bool, device: str,
    hand: str = "shadow",
) -> tuple[GraspSet, dict]:
    """The ``keep`` best-scored distinct ``candidates`` per object (a data-loop round's, on training objects), with their
    ``evaluator_score`` and ``evaluator_rank``; and the ranking's attributes (pool and kept counts, CPU seconds). The
    evaluator must be of ``hand`` (config key ``hand``): refused in one line otherwise."""
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.evaluator import load_evaluator, score_grasps
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.tabletop import load_support_planes

    started = time.process_time()  # CPU seconds (all threads of this process), not wall time
    attrs = {"evaluator": str(evaluator_path), "pool": len(candidates), "kept_per_object": keep}
    if not len(candidates):
        return candidates, {**attrs, "kept": 0, "cpu_seconds": 0.0}
    from dexlite_pipeline.hand.choice import hand_record

    device = resolve_device(device)
    evaluator, _ = load_evaluator(evaluator_path, device, hand=hand_record(hand))
    planes = load_support_planes(table, stability_path)
    ids = candidates.object_id.astype(str).astype(object)
    clouds = ObjectClouds([load_asset(objects_dirs, oid) for oid in sorted(set(ids.tolist()))])
    scores = score_grasps(evaluator, candidates.hand_pose, clouds, ids, candidates.scale, support=support_rows(planes, ids, candidates.scale))
    chosen, place = best_distinct(scores, np.asarray(candidates.hand_pose), ids, keep, diversity)
    kept = candidates.select(chosen)
    kept.arrays[SCORE] = scores[chosen].astype(np.float32)
    kept.arrays[RANK] = place
    attrs.update(kept=int(len(chosen)), cpu_seconds=time.process_time() - started, pool_mean_score=float(np.mean(scores)),
                 kept_mean_score=float(np.mean(scores[chosen])))
    log.info("ranking: %d of %d candidates kept (mean score %.3f -> %.3f)", len(chosen), len(candidates), attrs["pool_mean_score"],
             attrs["kept_mean_score"])
    return kept, attrs


def rank_shard(
    sampled: GraspSet, model_path: str, evaluator_path: str, objects_dirs: list[str], stability_path: str, shard: int, *, shards: int,
    sample, section, diversity, table: bool, seed: int, device: str, hand: str = "shadow", evaluated_per_object: int | None = None,
) -> tuple[GraspSet, dict]:
    """``sampled`` (the shard's sample store) with the ranked rows appended and ``evaluator_score`` on its pure syntheses.
    The model and the evaluator must be of ``hand`` (config key ``hand``): each is refused in one line otherwise.

    ``sample``: ``SampleConfig``; ``section``: ``EvaluatorSection`` (pool_factor); ``evaluated_per_object``: the
    evaluation's cap (``evaluate.grasps_per_object``; None: as many as ``sample.synthesis_grasps_per_object``);
    ``diversity``: ``DiversityConfig``
    (what "distinct" means); ``table``: tabletop mode (the evaluator reads each grasp's table). Returns the store and
    the ranking's attributes (pool and kept counts, CPU seconds of the pool's sampling and scoring per kept row).
    """
    import torch

    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.loop.round_basics import HELDOUT
    from dexlite_pipeline.loop.round_objects import round_objects
    from dexlite_pipeline.model.checkpoint import cloud_reading, load_checkpoint
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.evaluator import load_evaluator, score_grasps
    from dexlite_pipeline.model.methods import SYNTHESIS
    from dexlite_pipeline.model.sampling import synthesis_rows
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.sharding import shard_generator
    from dexlite_pipeline.tabletop import load_support_planes

    from dexlite_pipeline.hand.choice import hand_record

    started = time.process_time()  # CPU seconds (all threads of this process), not wall time
    device = resolve_device(device)
    record = hand_record(hand)
    evaluator, evaluator_meta = load_evaluator(evaluator_path, device, hand=record)
    planes = load_support_planes(table, stability_path)
    object_ids, skipped = round_objects(objects_dirs, stability_path, shard, shards, HELDOUT)
    if planes is not None:
        skipped.update({oid: "no resting pose (tabletop mode)" for oid in object_ids if oid not in planes})
        object_ids = [oid for oid in object_ids if oid in planes]
    # as many ranked rows per object as the evaluation simulates of the unranked ones (its cap, evaluated_per_object), drawn
    # from pool_factor times as many: every simulated ranked grasp is the best of pool_factor candidates, as in dexlite grasp
    keep = sample.synthesis_grasps_per_object if evaluated_per_object is None else min(sample.synthesis_grasps_per_object, evaluated_per_object)
    pool_size = keep * section.pool_factor
    arrays = dict(sampled.arrays)
    n = len(sampled)
    arrays[SCORE] = np.full(n, np.nan, np.float32)
    arrays[KEPT_FRACTION] = np.full(n, 1.0 / section.pool_factor, np.float32)
    arrays[RANK] = np.full(n, -1, np.int32)
    attrs = {"pool_factor": section.pool_factor, "kept_per_object": keep, "evaluator": str(evaluator_path),
             "evaluator_train_objects": len(evaluator_meta.get("train_object_ids", [])), "skipped_objects": skipped}
    if not object_ids or keep <= 0:
        attrs.update(pool=0, kept=0, ranked_seconds_per_grasp=None)
        return GraspSet(arrays, sampled.attrs), attrs
    leaked = sorted(set(object_ids) & set(evaluator_meta.get("train_object_ids", [])))
    if leaked:
        raise ValueError(f"{evaluator_path}: the evaluator was trained on held-out object(s) {', '.join(leaked[:5])}: it would rank what it has seen")
    model, checkpoint = load_checkpoint(model_path, device, hand=record)
    points, fixed_clouds = cloud_reading(checkpoint, sample.points_per_cloud)
    clouds = ObjectClouds([load_asset(objects_dirs, oid) for oid in object_ids], model.codes_mu.device, planes)
    with torch.no_grad():
        pool = synthesis_rows(model, clouds, object_ids, sample, points, shard_generator("evaluator_ranking", seed, shard), fixed_clouds,
                              RANKED_METHOD, pool_size)
    pool_pose = pool.hand_pose.cpu().numpy()
    pool_ids = np.asarray(pool.object_id, dtype=object)
    scores = score_grasps(evaluator, pool_pose, clouds, pool_ids, pool.scale, support=support_rows(planes, pool_ids, pool.scale))
    chosen, place = best_distinct(scores, pool_pose, pool_ids, keep, diversity)
    seconds = time.process_time() - started

    raw = np.asarray([str(m) for m in sampled.arrays.get("method", np.full(n, SYNTHESIS, dtype=object))]) == SYNTHESIS
    finite = raw & np.isfinite(sampled.hand_pose).all(axis=1) & np.isin(sampled.object_id.astype(str), object_ids)
    if finite.any():
        rows = np.flatnonzero(finite)
        ids = sampled.object_id[rows].astype(str)
        arrays[SCORE][rows] = score_grasps(evaluator, sampled.hand_pose[rows], clouds, ids, sampled.scale[rows],
                                           support=support_rows(planes, ids, sampled.scale[rows]))
    blank = {"f": np.nan, "c": np.nan, "O": "", "U": "", "i": -1, "u": 0, "b": False}  # a ranked row's value of the other arrays
    ranked = {name: np.full((len(chosen), *values.shape[1:]), blank.get(values.dtype.kind, 0), dtype=values.dtype) for name, values in arrays.items()}
    ranked.update({"hand_pose": pool_pose[chosen].astype(sampled.hand_pose.dtype), "object_id": pool_ids[chosen], "scale": pool.scale[chosen].astype(sampled.scale.dtype),
                   "method": np.full(len(chosen), RANKED_METHOD, dtype=object), SCORE: scores[chosen].astype(np.float32),
                   KEPT_FRACTION: np.full(len(chosen), len(chosen) / len(pool_ids), np.float32), RANK: place})
    if GRASP_TYPE in arrays:  # each ranked row's type, as sampled
        ranked[GRASP_TYPE] = np.asarray(pool.types(), dtype=object)[chosen]
    merged = {name: np.concatenate([arrays[name], ranked[name]]) for name in arrays}
    attrs.update(pool=int(len(pool_ids)), kept=int(len(chosen)), cpu_seconds=seconds, ranked_seconds_per_grasp=seconds / len(chosen),
                 pool_mean_score=float(np.mean(scores)), kept_mean_score=float(np.mean(scores[chosen])))
    log.info("ranking, shard %03d: %d of %d pooled syntheses kept on %d held-out objects (mean score %.3f -> %.3f), %.1f CPU s", shard,
             len(chosen), len(pool_ids), len(object_ids), attrs["pool_mean_score"], attrs["kept_mean_score"], seconds)
    return GraspSet(merged, sampled.attrs), attrs
