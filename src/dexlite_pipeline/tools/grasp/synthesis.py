"""Grasp synthesis of ``dexlite grasp``: CVAE samples refined by post-optimization (sections ``sample`` and
``post_optimize``), energy optimization from scratch (section ``optimize_grasps``), and the top-up that adds
batches of optimization from scratch to the objects with too few distinct held grasps.

Scales: at the real size an object's scale is the mesh file's unit in metres divided by the asset's
``normalization_factor``; with ``resize_to_training`` it takes the configured training scales.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from dexlite_pipeline.sharding import shard_generator
from dexlite_pipeline.tools.grasp.request import UNIT_METRES, GraspRequest, GraspToolError
from dexlite_pipeline.tools.grasp.selection import distinct_labels, distinct_per_object

if TYPE_CHECKING:
    import torch

    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.objects.assets import ObjectAsset
    from dexlite_pipeline.settings import PipelineConfig
    from dexlite_pipeline.tabletop import SupportPlanes

log = logging.getLogger("dexlite.grasp")

# A missing array of one source is filled for the other source's rows with this value, by dtype kind.
NOT_MADE = {"f": np.nan, "i": -1, "u": 0, "b": False, "O": ""}


def object_scales(assets: list[ObjectAsset], request: GraspRequest, configured: tuple[float, ...]) -> dict[str, tuple[float, ...]]:
    """Scales per object: the real size (file unit in metres / normalization factor), or the configured ones."""
    if request.resize_to_training:
        return {a.object_id: tuple(configured) for a in assets}
    unit_m = UNIT_METRES[request.units]
    scales = {}
    for asset in assets:
        factor = float(asset.meta.get("normalization_factor", math.nan))
        if not math.isfinite(factor) or factor <= 0:
            raise GraspToolError(f"{asset.object_id}: asset has no normalization factor; cannot keep its real size")
        scales[asset.object_id] = (unit_m / factor,)
    return scales


def _balanced_rows(per_scale: int, scale_count: int, wanted: int) -> np.ndarray:
    """Rows of a scale-major block (``per_scale`` grasps per scale) taking ``wanted``, the scales in turn."""
    k = np.arange(per_scale * scale_count)
    order = np.lexsort((k // per_scale, k % per_scale))
    return np.sort(order[:wanted])


def starts_per_scale(n: int, object_scales: list[tuple[float, ...]]) -> int:
    """Starts optimized at each scale so that every object has ``n`` grasps, taken from its scales in turn."""
    return -(-n // min(len(s) for s in object_scales))


def synthesize_from_scratch(
    assets: list[ObjectAsset], scales: dict[str, tuple[float, ...]], n: int, config: PipelineConfig, device: torch.device, seed: int,
    support_planes: SupportPlanes | None = None, hand=None, type_plans: dict[str, np.ndarray] | None = None,
) -> GraspSet:
    """``n`` grasps per object by energy optimization from convex-hull starts (section ``optimize_grasps``), with ``hand``
    (None: the Shadow Hand; ``hand.choice.resolve_hand``). ``type_plans``: object id -> the grasp type codes of its
    ``starts_per_scale`` starts at each scale (``type_rounds``), instead of the configured shares."""
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.optim.from_scratch import synthesize

    generator = shard_generator("optimize_grasps", seed, 0)
    object_scales = [tuple(scales[a.object_id]) for a in assets]
    per_scale = starts_per_scale(n, object_scales)
    optimize_config = dataclasses.replace(config.optimize_grasps, grasps_per_object=per_scale)
    log.info("optimizing %d grasps on %d object(s) together, %d iterations", per_scale * sum(len(s) for s in object_scales), len(assets),
             optimize_config.annealing.iterations)
    plans = None if type_plans is None else [type_plans[a.object_id] for a in assets]
    optimized, _ = synthesize(assets, optimize_config, config.energy, generator, device, support_planes=support_planes,
                              object_scales=object_scales, keyed_seed=seed, hand=hand, type_plans=plans)  # an object's grasps whatever other meshes are given
    parts, start = [], 0
    for object_scale in object_scales:
        block = per_scale * len(object_scale)
        parts.append(optimized.select(start + _balanced_rows(per_scale, len(object_scale), n)))
        start += block
    grasps = GraspSet.concatenate(parts)
    grasps.arrays["method"] = np.full(len(grasps), "optimization", dtype=object)
    return grasps


def rank_samples(
    poses: torch.Tensor, object_ids: np.ndarray, scale: np.ndarray, clouds, evaluator: tuple, n: int, config: PipelineConfig,
    support_planes: SupportPlanes | None,
) -> tuple[np.ndarray, np.ndarray]:
    """(rows kept, their scores): the ``n`` best-scored distinct sampled ``poses`` per object by the learned evaluator
    (what "distinct" means: section ``diversity``), topped up with the next best where fewer are distinct."""
    from dexlite_pipeline.evaluator.ranking import best_distinct, support_rows
    from dexlite_pipeline.model.evaluator import score_grasps

    model, _ = evaluator
    pose_array = poses.detach().cpu().numpy()
    scores = score_grasps(model, pose_array, clouds, object_ids, scale, support=support_rows(support_planes, object_ids, scale))
    chosen, _ = best_distinct(scores, pose_array, object_ids, n, config.diversity)
    log.info("evaluator: kept the %d best-scored distinct of %d samples (mean predicted held %.2f -> %.2f)", len(chosen), len(scores),
             float(np.mean(scores)), float(np.mean(scores[chosen])))
    return chosen, scores[chosen].astype(np.float32)


def synthesize_with_model(
    assets: list[ObjectAsset], scales: dict[str, tuple[float, ...]], n: int, config: PipelineConfig, loaded: tuple, model_path: str,
    device: torch.device, seed: int, support_planes: SupportPlanes | None = None, evaluator: tuple | None = None, hand=None,
) -> GraspSet:
    """``n`` CVAE samples per object, refined by post-optimization (sections ``sample``, ``post_optimize``); with an
    ``evaluator`` (model, meta), ``evaluator.pool_factor`` x ``n`` samples per object ranked, the ``n`` best distinct kept.
    Each sample is of the type ``sample.grasp_type`` asks for (``type_condition.requested_codes``), refined with that type's
    contact template, and records it in ``grasp_type``. ``hand``: the hand model the model is of (None: the Shadow Hand;
    ``hand.choice.resolve_hand``), whose energies refine the samples, in groups of ``post_optimize.objects_per_energy``
    objects (one energy per group, built and released in turn) when there are more."""
    import torch

    from dexlite_pipeline.energy.config import EnergyConfig
    from dexlite_pipeline.energy.grasp_energy import GraspEnergy, energy_groups, max_scale_by_object
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.model.checkpoint import cloud_reading
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.sampling import synthesize
    from dexlite_pipeline.model.type_condition import requested_codes
    from dexlite_pipeline.optim.grasp_types import slots_of_types
    from dexlite_pipeline.optim.post import merged_refinement, refine

    sample_config, post_config = config.sample, config.post_optimize
    model, checkpoint = loaded
    points, fixed = cloud_reading(checkpoint, sample_config.points_per_cloud)
    clouds = ObjectClouds(assets, device, support_planes)
    drawn = n * (config.evaluator.pool_factor if evaluator is not None else 1)  # samples drawn per object
    object_index = np.repeat(np.arange(len(assets)), drawn)
    types = np.tile(requested_codes(model.type_vocabulary, model.codes_type.cpu().numpy(), sample_config.grasp_type, drawn,
                                     sample_config.type_mix), len(assets))
    scale = np.concatenate([np.resize(np.asarray(scales[a.object_id], np.float32), drawn) for a in assets])
    training_scales = (checkpoint.get("training_grasps") or {}).get("scale")
    # the training grasps' scales (a model trained at real sizes has many), else the configured ones
    trained = sorted({float(s) for s in np.asarray(training_scales)}) if training_scales is not None and len(training_scales) else \
        sorted(float(s) for s in sample_config.scales)
    outside = sorted({round(float(s), 4) for s in scale if not min(trained) * 0.8 <= s <= max(trained) * 1.25})
    if outside:
        log.info("object radii %s m are outside the model's training radii (%.3f-%.3f m): expect fewer grasps that hold", outside,
                 trained[0], trained[-1])
    generator = shard_generator("grasp_tool_post_optimize", seed, 0)
    log.info("sampling %d grasps from %s", len(object_index), model_path)
    prior, anchor_rule = sample_config.latent_prior, sample_config.anchor_rule
    if len(model.codes_mu) == 0 or len(model.codes_condition) == 0:  # a model saved without its training codes
        log.warning("%s holds no training codes: sampling from N(0, I) at uniform points instead of %s / %s", model_path, prior, anchor_rule)
        prior, anchor_rule = "standard", "uniform"
    poses = synthesize(
        model, clouds, object_index, scale, points, generator, prior, sample_config.latent_temperature, fixed, anchor_rule,
        sample_config.neighbour_clouds, sample_config.anchor_region_m, sample_config.debias_training, sample_config.match_candidates,
        sample_config.debias_codes, sample_config.yaw_candidates, types,
    )
    scores = None
    if evaluator is not None:
        ids = np.asarray([assets[i].object_id for i in object_index], dtype=object)
        chosen, scores = rank_samples(poses, ids, scale, clouds, evaluator, n, config, support_planes)
        poses, object_index, scale, types = poses[torch.as_tensor(chosen, device=poses.device)], object_index[chosen], scale[chosen], types[chosen]
    if support_planes is not None:  # tabletop: samples whose hand starts below the table are raised above it first
        from dexlite_pipeline.energy.table_clearance import raise_above_table

        starts = GraspSet({"hand_pose": poses.detach().cpu().numpy(), "object_id": np.asarray([assets[i].object_id for i in object_index], dtype=object),
                           "scale": scale})  # fmt: skip
        from dexlite_pipeline.hand.described import is_described

        table_hand = hand if hand is not None and is_described(hand) else None  # None: the Shadow Hand on CPU, as before
        poses = torch.as_tensor(raise_above_table(starts, support_planes, table_hand)[0].hand_pose, dtype=poses.dtype, device=poses.device)
    hand = ShadowHand(device) if hand is None else hand
    energy_config = EnergyConfig(weights=post_config.energy_weights, object_point_spacing_m=post_config.energy_point_spacing_m,
                                 self_penetration_margin_m=config.energy.self_penetration_margin_m)
    log.info("post-optimizing %d grasps, %d iterations", len(object_index), post_config.annealing.iterations)
    type_names = np.asarray([model.grasp_types[t] for t in types.tolist()], dtype=object)
    # The objects in groups of post_optimize.objects_per_energy, each group's energy built, used and released in turn, so
    # memory does not grow with the number of meshes; one group (no more objects) is the refinement with one energy of all.
    groups = energy_groups(len(assets), post_config.objects_per_energy)
    parts = []
    for group in groups:
        group_assets = assets[group]
        rows = np.flatnonzero((object_index >= group.start) & (object_index < group.stop))
        if not len(rows):
            continue
        energy = GraspEnergy.from_assets(hand, group_assets, energy_config, support_planes=support_planes,
                                         max_scale=max_scale_by_object([assets[i].object_id for i in object_index[rows]], scale[rows]))
        parts.append((rows, refine(
            energy, poses[torch.as_tensor(rows, device=poses.device)], torch.as_tensor(object_index[rows] - group.start, device=device),
            torch.as_tensor(scale[rows], device=device), post_config, generator, "surface", slots_of_types(hand, type_names[rows]),
        )))  # fmt: skip
        del energy
        if len(groups) > 1:
            log.info("objects %d-%d of %d refined", group.start + 1, group.stop, len(assets))
    refined = merged_refinement(parts, len(object_index))
    arrays = {k: v for k, v in refined.arrays.items() if not k.startswith("trace_") and k != "energy_trace"}
    arrays["object_id"] = np.asarray([assets[i].object_id for i in object_index], dtype=object)
    arrays["scale"] = scale
    arrays["method"] = np.full(len(object_index), "cvae_post", dtype=object)
    arrays["grasp_type"] = type_names
    if scores is not None:
        arrays["evaluator_score"] = scores  # the evaluator's predicted chance that the sampled pose holds once refined
    return GraspSet(arrays)


def objects_to_top_up(assets: list[ObjectAsset], grasps: GraspSet, labels: np.ndarray, min_distinct: int) -> list[ObjectAsset]:
    """The assets whose grasps so far give fewer than ``min_distinct`` distinct held grasps (none when it is 0)."""
    counts = distinct_per_object(grasps, labels)
    return [a for a in assets if counts[a.object_id] < min_distinct]


def top_up_until_distinct(
    assets: list[ObjectAsset], tested: GraspSet, config: PipelineConfig, min_distinct: int, max_batches: int,
    optimized_batch: Callable[[list[ObjectAsset], int], GraspSet],
) -> tuple[GraspSet, list[str], list[ObjectAsset]]:
    """Add batches of optimization from scratch to the objects with fewer than ``min_distinct`` distinct held grasps.

    ``optimized_batch(chosen_assets, batch)`` makes and tests batch ``batch`` (0-based) for the chosen objects; after
    each batch the objects are counted again over every grasp so far (all sources together) and only those still
    short get the next one, for at most ``max_batches`` batches; an object to which a batch added no distinct held
    grasp gets no further batch (optimization from scratch found nothing that holds on it: another batch of the same
    kind would most likely cost as much for as little). Returns the grasps with the batches appended, the object ids
    that got at least one batch, and the assets still short after the last batch (those given up on included)."""
    labels = distinct_labels(tested, config)
    short = objects_to_top_up(assets, tested, labels, min_distinct)
    topped_up: list[str] = []
    given_up: list[ObjectAsset] = []
    for batch in range(max_batches):
        if not short:
            break
        if batch:
            log.info("top-up batch %d/%d: still fewer than %d distinct held grasps for %d object(s) (%s)", batch + 1, max_batches,
                     min_distinct, len(short), ", ".join(a.object_id for a in short))  # fmt: skip
        topped_up += [a.object_id for a in short if a.object_id not in topped_up]
        before = distinct_per_object(tested, labels)
        tested = concatenate_sources([tested, optimized_batch(short, batch)])
        labels = distinct_labels(tested, config)
        after = distinct_per_object(tested, labels)
        barren = [a for a in short if after.get(a.object_id, 0) <= before.get(a.object_id, 0)]
        if barren and batch + 1 < max_batches:
            log.info("top-up batch %d added no distinct held grasp to %d object(s), not topped up again (%s)", batch + 1, len(barren),
                     ", ".join(a.object_id for a in barren))  # fmt: skip
        given_up += barren
        barren_ids = {a.object_id for a in barren}
        short = [a for a in objects_to_top_up(short, tested, labels, min_distinct) if a.object_id not in barren_ids]
    return tested, topped_up, short + given_up


def top_up_seed(seed: int, batch: int) -> int:
    """The random seed of top-up batch ``batch`` (0-based): batch 0 has ``seed`` itself, so its grasps are those of
    ``--from-scratch``; later batches get independent streams derived from (seed, batch)."""
    return seed if batch == 0 else int(np.random.SeedSequence([seed, batch]).generate_state(1)[0])


def concatenate_sources(parts: list[GraspSet]) -> GraspSet:
    """The grasp sets of both sources as one; an array only one source has is filled for the other's rows (``NOT_MADE``)."""
    from dexlite_pipeline.io.grasp_store import GraspSet

    names = list(dict.fromkeys(k for part in parts for k in part.arrays))
    examples = {k: next(part.arrays[k] for part in parts if k in part.arrays) for k in names}
    arrays = {
        k: np.concatenate([
            part.arrays[k] if k in part.arrays
            else np.full((len(part), *examples[k].shape[1:]), NOT_MADE[examples[k].dtype.kind], dtype=examples[k].dtype)
            for part in parts
        ])
        for k in names
    }  # fmt: skip
    return GraspSet(arrays, dict(parts[0].attrs))
