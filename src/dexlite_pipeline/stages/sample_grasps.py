"""Stage ``sample_grasps`` (one shard): CVAE grasps for the shard's stable objects.

Held-out objects get pure synthesis (method ``cvae_raw``); training objects get dataset
expansion from their lift-validated grasps (``cvae_expand_latent`` / ``cvae_expand_point``)
and, with ``sample.ladder``, the learning ladder's rows (``cvae_recon``: reconstructions of
the grasps the model was trained on; ``cvae_prior_train``: pure synthesis on training objects).
Objects are grouped into shards exactly as the other grasp stages do
(``sharding.shard_objects`` over the stable objects of the catalogs). Objects that get no
grasps are listed with the reason in the store's ``skipped_objects`` attribute.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import time

import numpy as np

from dexlite_pipeline.config import from_section, parse_config_json
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store, write_grasp_store
from dexlite_pipeline.model.sampling import EXPAND_LATENT, EXPAND_POINT, SYNTHESIS, SampleConfig
from dexlite_pipeline.objects.stability import stable_object_ids
from dexlite_pipeline.stages.train_cvae import object_splits

log = logging.getLogger("dexlite.sample_grasps")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, device, shards, sample (canonical JSON)")
    parser.add_argument("--model", required=True, help="trained model (cvae.pt)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--stability", required=True, help="stability.parquet of the stability_filter stage")
    parser.add_argument("--lift", action="append", default=[], help="lift-validated grasp shard, the expansion seeds (repeatable)")
    parser.add_argument("--shard", required=True, help="shard id, e.g. 000")
    parser.add_argument("--out", required=True, help="output grasp store (.zarr)")


def known_grasps(paths: list[str], object_ids: set[str]) -> GraspSet:
    """Lift-successful grasps of ``object_ids`` from the lift shards (the expansion seeds)."""
    sets = []
    for p in paths:
        grasps = read_grasp_store(p)
        if not len(grasps):
            continue
        keep = np.asarray(grasps.arrays["lift_success"], bool) & np.isin(grasps.object_id.astype(str), list(object_ids))
        keep &= np.isfinite(grasps.hand_pose).all(axis=1)
        sets.append(GraspSet({k: grasps.arrays[k][keep] for k in ("hand_pose", "object_id", "scale")}, {}))
    return GraspSet.concatenate(sets)


def run(args: argparse.Namespace) -> int:
    import torch

    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.model.association import grasp_rays
    from dexlite_pipeline.model.checkpoint import load_checkpoint
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.sampling import expand, ladder_rows, synthesis_rows
    from dexlite_pipeline.objects.assets import available_object_ids, load_asset
    from dexlite_pipeline.sharding import shard_objects

    cfg = parse_config_json(args.config_json)
    config = from_section(SampleConfig, cfg.get("sample"), "config.sample")
    seed = int(cfg.get("seed", 0))
    shard = int(args.shard)
    device = resolve_device(cfg.get("device", "auto"))
    model, checkpoint = load_checkpoint(args.model, device)
    points = config.points_per_cloud or int(checkpoint["train_config"]["points_per_cloud"])

    splits = object_splits(args.objects)
    stable = stable_object_ids(args.stability)
    ids = shard_objects(sorted(stable & set(splits)), shard, int(cfg["shards"]))
    available = available_object_ids(args.objects)
    skipped = {oid: "no prepared asset" for oid in ids if oid not in available}
    ids = [oid for oid in ids if oid in available]
    heldout = [oid for oid in ids if splits[oid] == "heldout"]
    seeds = known_grasps(args.lift, {oid for oid in ids if splits[oid] == "train"})
    seeded = set(seeds.object_id.tolist())
    skipped.update({oid: "training object without lift-validated grasps to expand" for oid in ids if splits[oid] == "train" and oid not in seeded})
    model_train_ids = set(checkpoint.get("train_object_ids") or [])
    ladder_ids = sorted(oid for oid in ids if splits[oid] == "train" and oid in model_train_ids) if config.ladder else []
    fixed_clouds = bool(checkpoint["train_config"].get("fixed_clouds", False))
    targets = sorted(set(heldout) | seeded | set(ladder_ids))
    generator = torch.Generator().manual_seed(seed * 1000 + shard)
    started = time.perf_counter()
    poses, object_ids, scales, methods = [], [], [], []
    reference_pose = None
    if targets:
        assets = [load_asset(args.objects, oid) for oid in targets]
        clouds = ObjectClouds(assets, device)
        if heldout and config.synthesis_grasps_per_object > 0:
            synthesized = synthesis_rows(model, clouds, heldout, config, points, generator, fixed_clouds, SYNTHESIS)
            poses.append(synthesized.hand_pose)
            object_ids += synthesized.object_id
            scales.append(synthesized.scale)
            methods += synthesized.method
        if len(seeds) and config.expansion_grasps_per_object > 0:
            pick = np.concatenate([
                np.flatnonzero(seeds.object_id == oid)[np.arange(config.expansion_grasps_per_object) % int((seeds.object_id == oid).sum())]
                for oid in sorted(seeded)
            ])
            known = torch.as_tensor(seeds.hand_pose[pick], dtype=torch.float32, device=device)
            origin, direction = grasp_rays(ShadowHand(device), known)
            obj = np.array([clouds.index_of[o] for o in seeds.object_id[pick]])
            scale = seeds.scale[pick].astype(np.float32)
            move_point = torch.rand(len(pick), generator=generator) < config.expansion_point_fraction
            poses.append(expand(model, clouds, known, origin, direction, obj, scale, move_point.to(device), config, points, generator, fixed_clouds))
            object_ids += [clouds.object_ids[i] for i in obj]
            scales.append(scale)
            methods += [EXPAND_POINT if m else EXPAND_LATENT for m in move_point.tolist()]
        if ladder_ids and "training_grasps" in checkpoint:
            ladder = ladder_rows(model, checkpoint["training_grasps"], clouds, ladder_ids, config, points, generator, ShadowHand(device), fixed_clouds)
            references = np.full((sum(len(p) for p in poses), 28), np.nan, np.float32)
            poses.append(ladder.hand_pose)
            object_ids += ladder.object_id
            scales.append(ladder.scale)
            methods += ladder.method
            reference_pose = np.concatenate([references, ladder.reference_pose])
        elif ladder_ids:
            log.warning("%s: the model file holds no training grasps, so the learning ladder's rows are not sampled", args.model)
    seconds = time.perf_counter() - started
    count = sum(len(p) for p in poses)
    arrays = {
        "hand_pose": torch.cat(poses).cpu().numpy() if poses else np.zeros((0, 28), np.float32),
        "object_id": np.asarray(object_ids, dtype=object),
        "scale": np.concatenate(scales) if scales else np.zeros(0, np.float32),
        "method": np.asarray(methods, dtype=object),
    }
    # the known grasp each ladder reconstruction reproduces (NaN for other rows): the fit rung's pose errors
    arrays["reference_hand_pose"] = reference_pose if reference_pose is not None else np.full((count, 28), np.nan, np.float32)
    attrs = {
        "stage": "sample_grasps",
        "shard": args.shard,
        "config": {"seed": seed, "sample": json_ready(dataclasses.asdict(config)), "points_per_cloud": points},
        "model_seed": checkpoint.get("seed"),
        "model_steps": checkpoint.get("steps"),
        "seconds_per_grasp": seconds / count if count else None,
        "skipped_objects": skipped,
    }
    write_grasp_store(args.out, GraspSet(arrays, {}), attrs)
    log.info(
        "shard %s: %d grasps (%d synthesized on %d held-out objects, %d expansions on %d training objects) in %.2fs; skipped %d objects",
        args.shard, count, methods.count(SYNTHESIS), len(heldout), count - methods.count(SYNTHESIS), len(seeded), seconds, len(skipped),
    )
    return 0


def json_ready(values: dict) -> dict:
    """Tuples as lists, so attributes survive JSON."""
    return {k: list(v) if isinstance(v, tuple) else v for k, v in values.items()}
