"""Stage ``post_optimize`` (one shard): refine the CVAE's grasps by 200 annealed steps on E_post.

Writes ``--out`` with the refined pose (``hand_pose``) beside the sampled one
(``raw_hand_pose``), every energy term before (``raw_E_*``) and after (``E_*``), and the
per-iteration traces (``trace_E_post`` etc., attribute ``trace_iterations``). With
``post_optimize.random_baseline`` it also writes ``--random-out``: the same optimization
from random convex-hull starts for the same held-out objects and scales as the shard's
pure syntheses (``cvae_raw``), the baseline for "CVAE starts converge faster".
"""

from __future__ import annotations

import argparse
import dataclasses
import logging

import numpy as np

from dexlite_pipeline.config import from_section, parse_config_json
from dexlite_pipeline.io.grasp_store import GraspSet, invalid_grasp_reasons, read_grasp_store, write_grasp_store
from dexlite_pipeline.model.post_optimization import PostOptimizeConfig
from dexlite_pipeline.model.sampling import SYNTHESIS

log = logging.getLogger("dexlite.post_optimize")
RANDOM_METHOD = "random_post"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, device, energy, post_optimize (canonical JSON)")
    parser.add_argument("--sample", required=True, help="sampled grasp shard (sample_grasps output)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir (repeatable)")
    parser.add_argument("--shard", required=True, help="shard id, e.g. 000")
    parser.add_argument("--out", required=True, help="refined grasp store (.zarr)")
    parser.add_argument("--random-out", required=True, help="random-init baseline store (.zarr; no rows when post_optimize.random_baseline is off)")


def _config_attrs(seed: int, config: PostOptimizeConfig, spen_margin_m: float) -> dict:
    values = dataclasses.asdict(config)
    values["random_init"]["distance_m"] = list(values["random_init"]["distance_m"])
    return {"seed": seed, "post_optimize": values, "energy": {"self_penetration_margin_m": spen_margin_m}}


def _store_arrays(grasps: GraspSet, refined, reasons: np.ndarray, method: np.ndarray) -> dict[str, np.ndarray]:
    """Refined arrays for the valid rows; invalid rows keep their raw pose, NaN results and their reason."""
    arrays = _empty_refined(grasps, reasons, method)
    valid = reasons == ""
    for name, values in refined.arrays.items():
        full = np.full((len(grasps), *values.shape[1:]), -1 if values.dtype.kind == "i" else np.nan, dtype=values.dtype)
        full[valid] = values
        arrays["trace_E_post" if name == "energy_trace" else name] = full
    arrays["raw_hand_pose"][~valid] = grasps.hand_pose[~valid]
    return arrays


def run(args: argparse.Namespace) -> int:
    import torch

    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.energy.grasp_energy import EnergyConfig, GraspEnergy
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.model.post_optimization import refine
    from dexlite_pipeline.objects.assets import available_object_ids, load_asset
    from dexlite_pipeline.optim.init import HullSampler, initial_poses

    cfg = parse_config_json(args.config_json)
    config = from_section(PostOptimizeConfig, cfg.get("post_optimize"), "config.post_optimize")
    seed = int(cfg.get("seed", 0))
    spen_margin_m = from_section(EnergyConfig, cfg.get("energy"), "config.energy").self_penetration_margin_m
    shard = int(args.shard)
    device = resolve_device(cfg.get("device", "auto"))
    sampled = read_grasp_store(args.sample)
    method = np.asarray(sampled.arrays.get("method", np.full(len(sampled), SYNTHESIS, dtype=object)), dtype=object)
    reasons = invalid_grasp_reasons(sampled, available_object_ids(args.objects))
    valid = reasons == ""
    object_ids = sorted(set(sampled.object_id[valid].tolist()))
    hand = ShadowHand(device)
    attrs = {
        "stage": "post_optimize",
        "shard": args.shard,
        "config": _config_attrs(seed, config, spen_margin_m),
        "trace_iterations": list(range(config.iterations + 1)),
        "budget_iterations": list(config.budget()),
        "sample_seconds_per_grasp": sampled.attrs.get("seconds_per_grasp"),
    }
    if object_ids:
        assets = [load_asset(args.objects, oid) for oid in object_ids]
        energy = GraspEnergy.from_assets(
            hand, assets, EnergyConfig(weights=config.weights(), object_points=config.energy_object_points, self_penetration_margin_m=spen_margin_m)
        )
    generator = torch.Generator().manual_seed(seed * 1000 + shard + 500)

    def optimize_rows(rows: GraspSet, init_pose: torch.Tensor | None, start_contacts: str):
        obj = energy.object_index(rows.object_id)
        scale = torch.as_tensor(rows.scale, dtype=torch.float32, device=device)
        pose = torch.as_tensor(rows.hand_pose, dtype=torch.float32, device=device) if init_pose is None else init_pose
        return refine(energy, pose, obj, scale, config, generator, start_contacts)

    if valid.any():
        refined = optimize_rows(sampled.select(valid), None, "surface")
        attrs["trace_iterations"] = refined.trace_iterations.tolist()
        attrs["seconds_per_grasp"] = refined.seconds / int(valid.sum())
        log.info("shard %s: post-optimized %d grasps in %.1fs; median E_post %.3g -> %.3g", args.shard, int(valid.sum()), refined.seconds,
                 float(np.median(refined.arrays["raw_E_post"])), float(np.median(refined.arrays["E_post"])))
    else:
        refined = None
        attrs["seconds_per_grasp"] = None
    arrays = _store_arrays(sampled, refined, reasons, method) if refined else _empty_refined(sampled, reasons, method)
    write_grasp_store(args.out, GraspSet(arrays, {}), attrs)

    targets = sampled.select(valid & (method == SYNTHESIS) & config.random_baseline)
    random_attrs = {**attrs, "stage": "post_optimize_random_baseline", "random_baseline": config.random_baseline}
    if len(targets):
        obj = energy.object_index(targets.object_id)
        scale = torch.as_tensor(targets.scale, dtype=torch.float32, device=device)
        init = initial_poses(hand, HullSampler(assets), obj, scale, config.random_init, generator)
        baseline = optimize_rows(targets, init, "random")
        random_attrs["seconds_per_grasp"] = baseline.seconds / len(targets)
        log.info("shard %s: random-init baseline on %d grasps in %.1fs; median E_post %.3g -> %.3g", args.shard, len(targets),
                 baseline.seconds, float(np.median(baseline.arrays["raw_E_post"])), float(np.median(baseline.arrays["E_post"])))
        random_arrays = _store_arrays(targets, baseline, np.full(len(targets), "", dtype=object), np.full(len(targets), RANDOM_METHOD, dtype=object))
    else:
        random_attrs["seconds_per_grasp"] = None
        random_arrays = _empty_refined(targets, np.zeros(0, dtype=object), np.zeros(0, dtype=object))
    write_grasp_store(args.random_out, GraspSet(random_arrays, {}), random_attrs)
    return 0


def _empty_refined(grasps: GraspSet, reasons: np.ndarray, method: np.ndarray) -> dict[str, np.ndarray]:
    """No valid grasp to optimize: the raw poses with their reasons, refined pose NaN."""
    return {
        "hand_pose": np.full_like(grasps.hand_pose, np.nan),
        "raw_hand_pose": grasps.hand_pose.copy(),
        "object_id": grasps.object_id,
        "scale": grasps.scale,
        "method": method,
        "failure_reason": reasons,
    }
