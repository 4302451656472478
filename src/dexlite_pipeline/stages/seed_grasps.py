"""Stage ``seed_grasps`` (one shard): synthesize grasps from scratch for this shard's stable objects.

Objects: every object of the catalog(s) with status ok that the stability table marks
stable (train and held-out alike), dealt to shards by ``sharding.shard_objects``. Writes
``--out`` (grasp store) with every energy term, ``passes_energy_thresholds``, the initial
pose and the optimizer's acceptance rate per grasp; attributes hold the config,
``seconds_per_grasp``, the pass fraction and any object that could not be used, with its
reason.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from dexlite_pipeline.io.grasp_store import GraspSet

log = logging.getLogger("dexlite.seed_grasps")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, device, shards, energy, seed_grasps (canonical JSON)")
    parser.add_argument("--shard", required=True, help="shard id, e.g. 000")
    parser.add_argument("--stability", required=True, help="stability table (.parquet)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--out", required=True, help="output grasp store (.zarr)")


def stable_object_ids(objects_dirs: list[str], stability_path: str) -> list[str]:
    """Objects that are prepared (status ok) and stable, over all catalogs."""
    from dexlite_pipeline.objects.assets import ok_object_ids
    from dexlite_pipeline.objects.stability import stable_object_ids as stable_in_table

    return sorted(ok_object_ids(objects_dirs) & stable_in_table(stability_path))


def empty_seed_grasps() -> GraspSet:
    """A zero-row shard with every array ``optim.seed.synthesize`` writes (dtypes and trailing shapes alike).

    A shard without usable objects must still carry the energy arrays: curation keeps only
    the arrays all its inputs have, and E_fc, E_dis and E_pen are what it filters on.
    """
    from dexlite_pipeline.energy.grasp_energy import CONTACT_COUNT, TERM_NAMES
    from dexlite_pipeline.hand.model import POSE_DIM
    from dexlite_pipeline.io.grasp_store import empty_grasp_set

    grasps = empty_grasp_set()
    grasps.arrays["init_pose"] = np.zeros((0, POSE_DIM), np.float32)
    grasps.arrays["contact_index"] = np.zeros((0, CONTACT_COUNT), np.int16)
    for name in ("acceptance_rate", "penetration_mm", "contact_distance_mm", "E_total", *TERM_NAMES):
        grasps.arrays[name] = np.zeros(0, np.float32)
    grasps.arrays["passes_energy_thresholds"] = np.zeros(0, bool)
    return grasps


def _jsonable(value):
    """Dataclass dicts with tuples turned into lists (for Zarr attributes)."""
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.config import from_section, parse_config_json
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.energy.grasp_energy import EnergyConfig
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.objects.assets import ObjectAssetError, load_asset
    from dexlite_pipeline.optim.seed import SeedConfig, seed_generator, synthesize
    from dexlite_pipeline.sharding import shard_objects

    cfg = parse_config_json(args.config_json)
    config = from_section(SeedConfig, cfg.get("seed_grasps"), "config.seed_grasps")
    energy_config = from_section(EnergyConfig, cfg.get("energy"), "config.energy")
    seed = int(cfg.get("seed", 0))
    shard = int(args.shard)
    shard_count = int(cfg.get("shards", 1))
    device = resolve_device(cfg.get("device") or "auto")

    object_ids = shard_objects(stable_object_ids(args.objects, args.stability), shard, shard_count)
    assets, failed = [], {}
    for object_id in object_ids:
        try:
            assets.append(load_asset(args.objects, object_id))
        except ObjectAssetError as exc:
            failed[object_id] = f"asset unusable: {exc}"
            log.warning("object %s skipped: %s", object_id, failed[object_id])
    # One SDF bank needs one grid size; objects with another are recorded, not dropped silently.
    if assets:
        resolution = max({a.sdf.shape for a in assets}, key=lambda s: sum(a.sdf.shape == s for a in assets))
        for asset in [a for a in assets if a.sdf.shape != resolution]:
            failed[asset.object_id] = f"SDF grid {asset.sdf.shape} differs from the shard's {resolution}"
            log.warning("object %s skipped: %s", asset.object_id, failed[asset.object_id])
        assets = [a for a in assets if a.sdf.shape == resolution]
    log.info(
        "shard %s: %d stable objects (%d usable), %d grasps each (%d scales), %d iterations, device %s",
        args.shard, len(object_ids), len(assets), config.grasps_per_object * len(config.scales), len(config.scales),
        config.annealing.iterations, device,
    )

    attrs = {
        "stage": "seed_grasps",
        "shard": args.shard,
        "seed": seed,
        "config": {"seed_grasps": _jsonable(dataclasses.asdict(config)), "energy": _jsonable(dataclasses.asdict(energy_config))},
        "objects": [a.object_id for a in assets],
        "failed_objects": failed,
    }
    if assets:
        grasps, stats = synthesize(assets, config, energy_config, seed_generator(seed, shard), device)
    else:
        grasps, stats = empty_seed_grasps(), {"grasps": 0, "passing": 0, "pass_fraction": 0.0, "seconds": 0.0, "seconds_per_grasp": 0.0}
    attrs.update(stats)
    attrs["passing_per_hour"] = stats["passing"] / stats["seconds"] * 3600 if stats["seconds"] else 0.0
    write_grasp_store(args.out, grasps, attrs)
    log.info(
        "shard %s: %d grasps, %d (%.1f%%) pass the energy thresholds, %.2f s per grasp, %.0f passing grasps/hour -> %s",
        args.shard, stats["grasps"], stats["passing"], 100 * stats["pass_fraction"], stats["seconds_per_grasp"], attrs["passing_per_hour"], args.out,
    )
    if len(grasps):
        per_object = np.unique(grasps.object_id[grasps.arrays["passes_energy_thresholds"]], return_counts=True)
        log.info("passing grasps per object: %s", dict(zip(per_object[0].tolist(), per_object[1].tolist())))
    return 0
