"""Post-optimization of one shard: the ``post_optimize`` stage's work.

The shard's sampled grasps are refined (``optim.post.refine``); with
``post_optimize.random_baseline`` the same budget also runs from random convex-hull starts for
the same held-out objects and scales as the shard's pure syntheses (``cvae_raw``).
"""

from __future__ import annotations

import logging
import time
from typing import TYPE_CHECKING

import numpy as np
import torch

from dexlite_pipeline.io.grasp_store import GRASP_TYPE, GraspSet, grasp_types
from dexlite_pipeline.energy.grasp_energy import GraspEnergy, energy_groups, max_scale_by_object
from dexlite_pipeline.optim.grasp_types import slots_of_types
from dexlite_pipeline.optim.post import RefinedGrasps, merged_refinement, refine

if TYPE_CHECKING:
    from dexlite_pipeline.optim.config import PostOptimizeConfig
    from dexlite_pipeline.sim.config import SceneConfig

log = logging.getLogger(__name__)

RANDOM_METHOD = "random_post"  # method label of the random-init baseline's grasps


def _store_arrays(grasps: GraspSet, refined: RefinedGrasps, reasons: np.ndarray, method: np.ndarray) -> dict[str, np.ndarray]:
    """Refined arrays for the valid rows; invalid rows keep their raw pose, NaN results and their reason."""
    arrays = _unrefined_arrays(grasps, reasons, method)
    valid = reasons == ""
    for name, values in refined.arrays.items():
        full = np.full((len(grasps), *values.shape[1:]), -1 if values.dtype.kind == "i" else np.nan, dtype=values.dtype)
        full[valid] = values
        arrays["trace_E_post" if name == "energy_trace" else name] = full
    arrays["raw_hand_pose"][~valid] = grasps.hand_pose[~valid]
    return arrays


def _unrefined_arrays(grasps: GraspSet, reasons: np.ndarray, method: np.ndarray) -> dict[str, np.ndarray]:
    """Rows not optimized: the raw poses with their reasons and grasp types, refined pose NaN."""
    return {
        "hand_pose": np.full_like(grasps.hand_pose, np.nan),
        "raw_hand_pose": grasps.hand_pose.copy(),
        "object_id": grasps.object_id,
        "scale": grasps.scale,
        "method": method,
        "failure_reason": reasons,
        GRASP_TYPE: grasp_types(grasps),
    }


def post_optimize_shard(
    sample_path: str, objects_dirs: list[str], shard: int, *, post_optimize: PostOptimizeConfig, self_penetration_margin_m: float,
    scene: SceneConfig, seed: int, device: str, stability_path: str | None = None, hand: str = "shadow",
) -> tuple[tuple[GraspSet, dict], tuple[GraspSet, dict]]:
    """Refine one shard's sampled grasps, and run the random-init baseline on its pure syntheses.

    Returns (refined grasps, attributes) and (baseline grasps, attributes). Every sampled row
    is kept: rows that cannot be optimized (invalid pose, unknown object) carry their
    ``failure_reason``. The baseline starts from convex-hull poses (``post_optimize.random_init``)
    for the same held-out objects and scales as the shard's ``cvae_raw`` rows, with the same budget.
    The config it reads comes as arguments: sections ``post_optimize`` and ``scene``,
    ``energy.self_penetration_margin_m`` (m), and the top-level ``seed``, ``device`` and ``hand`` (the hand whose model
    E_post, the starts and the table clearance use; the sampled store must be of it, and both stores record it).
    In tabletop mode (``scene.table``; resting poses from ``stability_path``) E_post includes E_table,
    sampled starts below the table are first raised above it (``raise_above_table``; the shift is
    stored as ``start_table_shift_m``), the random starts come from above it, and every row records
    its support plane. Rows of an object without a resting pose carry that reason and are not optimized. Each sampled
    row keeps its ``grasp_type`` and is refined with its type's contact template (``grasp_types.slots_of_types``).
    The refined rows' ``seconds_per_grasp`` (attributes) is the CPU time of the whole stage up to the end of their
    refinement (reading the stores, building the energy, raising starts, refining) over their number, as optimization
    from scratch counts its own; the baseline's, its starts and refinement.
    A shard of more than ``post_optimize.objects_per_energy`` objects is refined in groups of that many objects (sorted
    ids), each group's energy built and released in turn, so memory does not grow with the shard; its rows keep their
    places. A shard of no more objects is refined exactly as one energy of all its objects would.
    """
    started = time.process_time()  # CPU seconds of this process (all its threads)
    from dexlite_pipeline.tabletop import load_support_planes, store_attrs, support_arrays
    from dexlite_pipeline.config import json_ready
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.energy.config import EnergyConfig
    from dexlite_pipeline.hand.choice import SHADOW, hand_record, resolve_hand
    from dexlite_pipeline.io.grasp_store import GraspSet, invalid_grasp_reasons, read_grasp_store
    from dexlite_pipeline.model.hand_match import shards_hand
    from dexlite_pipeline.model.methods import SYNTHESIS
    from dexlite_pipeline.objects.assets import available_object_ids, load_asset
    from dexlite_pipeline.optim.init import HullSampler, initial_poses
    from dexlite_pipeline.sharding import shard_generator

    settings = post_optimize
    margin_m = self_penetration_margin_m
    device = resolve_device(device)
    record = hand_record(hand)
    sampled = read_grasp_store(sample_path)
    shards_hand([(sample_path, sampled.attrs)], hand)
    method = np.asarray(sampled.arrays.get("method", np.full(len(sampled), SYNTHESIS, dtype=object)), dtype=object)
    reasons = invalid_grasp_reasons(sampled, available_object_ids(objects_dirs))
    planes = load_support_planes(scene.table, stability_path)
    if planes is not None:
        no_plane = np.array([oid not in planes for oid in sampled.object_id], dtype=bool)
        reasons[(reasons == "") & no_plane] = "no resting pose (tabletop mode)"
    valid = reasons == ""
    object_ids = sorted(set(sampled.object_id[valid].tolist()))
    hand_model = resolve_hand(hand, device)
    attrs = {
        **record,
        "stage": "post_optimize",
        "shard": f"{shard:03d}",
        "config": {"seed": seed, "post_optimize": json_ready(settings), "energy": {"self_penetration_margin_m": margin_m}},
        "trace_iterations": list(range(settings.annealing.iterations + 1)),
        "budget_iterations": list(settings.budget()),
        "sample_seconds_per_grasp": sampled.attrs.get("seconds_per_grasp"),
    }
    if planes is not None:
        attrs["config"]["scene"] = {"table": True}
        attrs.update(store_attrs(True))
    energy_config = EnergyConfig(weights=settings.energy_weights, object_point_spacing_m=settings.energy_point_spacing_m, self_penetration_margin_m=margin_m)
    max_scale = max_scale_by_object(sampled.object_id[valid], sampled.scale[valid])
    generator = shard_generator("post_optimize", seed, shard)

    def optimize_rows(energy: GraspEnergy, rows: GraspSet, init_pose: torch.Tensor | None, start_contacts: str) -> RefinedGrasps:
        obj = energy.object_index(rows.object_id)
        scale = torch.as_tensor(rows.scale, dtype=torch.float32, device=device)
        pose = torch.as_tensor(rows.hand_pose, dtype=torch.float32, device=device) if init_pose is None else init_pose
        return refine(energy, pose, obj, scale, settings, generator, start_contacts, slots_of_types(hand_model, grasp_types(rows)))

    def random_starts(energy: GraspEnergy, group_assets: list, rows: GraspSet) -> torch.Tensor:
        obj = energy.object_index(rows.object_id)
        scale = torch.as_tensor(rows.scale, dtype=torch.float32, device=device)
        support = energy.support(obj, scale) if planes is not None else None
        return initial_poses(hand_model, HullSampler(group_assets), obj, scale, settings.random_init, generator, support=support)

    starts = sampled.select(valid)
    if valid.any() and planes is not None:
        from dexlite_pipeline.energy.table_clearance import raise_above_table

        starts, shift = raise_above_table(starts, planes, None if hand == SHADOW else hand_model)  # None: the Shadow Hand on CPU, as before
        log.info("shard %03d: %d of %d sampled starts raised above the table (median %.1f mm)", shard, int((shift > 0).sum()), len(shift),
                 1000 * float(np.median(shift[shift > 0])) if (shift > 0).any() else 0.0)
    targets = sampled.select(valid & (method == SYNTHESIS) & settings.random_baseline)
    targets.arrays[GRASP_TYPE] = np.full(len(targets), "power", dtype=object)  # convex-hull starts: power grasps
    # The shard's objects in groups of post_optimize.objects_per_energy, each group's energy built, used (its sampled rows
    # refined, then its random baseline) and released before the next: memory bounded by one group's objects. One group (a
    # shard of no more objects) is refinement and baseline over the whole shard, as one energy of every object would do.
    groups = energy_groups(len(object_ids), settings.objects_per_energy)
    refined_parts, baseline_parts, baseline_seconds = [], [], 0.0
    for span in groups:
        group = object_ids[span]
        group_assets = [load_asset(objects_dirs, oid) for oid in group]
        energy = GraspEnergy.from_assets(hand_model, group_assets, energy_config, support_planes=planes, max_scale=max_scale)
        rows = np.flatnonzero(np.isin(starts.object_id, group))
        refined_parts.append((rows, optimize_rows(energy, starts.select(rows), None, "surface")))
        target_rows = np.flatnonzero(np.isin(targets.object_id, group))
        if len(target_rows):
            baseline_started = time.process_time()
            group_targets = targets.select(target_rows)
            baseline_parts.append((target_rows, optimize_rows(energy, group_targets, random_starts(energy, group_assets, group_targets), "random")))
            baseline_seconds += time.process_time() - baseline_started
        del energy, group_assets
        if len(groups) > 1:
            log.info("shard %03d: objects %d-%d of %d refined", shard, span.start + 1, span.stop, len(object_ids))

    if valid.any():
        refined = merged_refinement(refined_parts, len(starts))
        if planes is not None:
            refined.arrays["start_table_shift_m"] = shift.astype(np.float32)
            refined.arrays["raw_hand_pose"] = sampled.hand_pose[valid].copy()  # the sampled pose, before the raise
        attrs["trace_iterations"] = refined.trace_iterations.tolist()
        attrs["seconds_per_grasp"] = (time.process_time() - started - baseline_seconds) / int(valid.sum())
        attrs["stopped_early"] = int((refined.arrays["stopped_at_iteration"] > 0).sum())
        log.info("shard %03d: post-optimized %d grasps in %.1fs (%d stopped early as hopeless); median E_post %.3g -> %.3g", shard,
                 int(valid.sum()), refined.seconds, attrs["stopped_early"], float(np.median(refined.arrays["raw_E_post"])),
                 float(np.median(refined.arrays["E_post"])))
        arrays = _store_arrays(sampled, refined, reasons, method)
    else:
        attrs["seconds_per_grasp"] = None
        arrays = _unrefined_arrays(sampled, reasons, method)

    random_attrs = {**attrs, "stage": "post_optimize_random_baseline", "random_baseline": settings.random_baseline}
    if len(targets):
        baseline = merged_refinement(baseline_parts, len(targets))
        random_attrs["seconds_per_grasp"] = baseline_seconds / len(targets)
        log.info("shard %03d: random-init baseline on %d grasps in %.1fs; median E_post %.3g -> %.3g", shard, len(targets),
                 baseline.seconds, float(np.median(baseline.arrays["raw_E_post"])), float(np.median(baseline.arrays["E_post"])))
        random_arrays = _store_arrays(targets, baseline, np.full(len(targets), "", dtype=object), np.full(len(targets), RANDOM_METHOD, dtype=object))
    else:
        random_attrs["seconds_per_grasp"] = None
        random_arrays = _unrefined_arrays(targets, np.zeros(0, dtype=object), np.zeros(0, dtype=object))
    if planes is not None:
        arrays.update(support_arrays(planes, sampled.object_id, sampled.scale))
        random_arrays.update(support_arrays(planes, targets.object_id, targets.scale))
    return (GraspSet(arrays, {}), attrs), (GraspSet(random_arrays, {}), random_attrs)
