"""Stage ``optimize_grasps`` (one shard): optimize grasps from scratch for this shard's stable objects.

Objects: every object of the catalog(s) with status ok that the stability table marks
stable (train and held-out alike), dealt to shards by ``sharding.shard_objects``. Writes
``--out`` (grasp store) with every energy term, ``passes_energy_thresholds``, the initial
pose and the optimizer's acceptance rate per grasp; attributes hold the hand (config key ``hand``), the config,
``seconds_per_grasp``, the pass fraction and any object that could not be used, with its
reason (``optim.from_scratch_shard``).
"""

from __future__ import annotations

import argparse
import logging

log = logging.getLogger("dexlite.optimize_grasps")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, device, shards, hand, energy, scene, optimize_grasps (canonical JSON)")
    parser.add_argument("--shard", required=True, type=int, help="shard number, e.g. 000")
    parser.add_argument("--stability", required=True, help="stability table (.parquet)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--out", required=True, help="output grasp store (.zarr)")
    parser.add_argument("--dataset", default=None, help="a grasp dataset (config dataset.root): the training objects it holds are not optimized")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.optim.from_scratch_shard import optimize_shard
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    from_dataset = set()
    if args.dataset:
        from dexlite_pipeline.dataset.for_run import dataset_training_objects

        from_dataset = dataset_training_objects(args.dataset, args.objects)
    grasps, attrs = optimize_shard(
        args.objects, args.stability, args.shard, shards=config.shards, optimize_grasps=config.optimize_grasps, energy=config.energy,
        scene=config.scene, seed=config.seed, device=config.device, skip_objects=from_dataset, hand=config.hand,
    )
    write_grasp_store(args.out, grasps, attrs)
    log.info(
        "shard %03d: %d grasps, %d (%.1f%%) pass the energy thresholds, %.2f s per grasp, %.0f passing grasps/hour -> %s",
        args.shard, attrs["grasps"], attrs["passing"], 100 * attrs["pass_fraction"], attrs["seconds_per_grasp"], attrs["passing_per_hour"], args.out,
    )
    return 0
