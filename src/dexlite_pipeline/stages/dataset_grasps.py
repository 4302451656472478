"""Stage ``dataset_grasps`` (one shard): the grasp dataset's grasps of the shard's training objects, as training data
(``dataset.for_run``; config ``dataset.root``). The dataset must be of config key ``hand`` (one hand per dataset;
refused in one line otherwise)."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections shards, scene and hand (JSON; hand absent: the Shadow Hand)")
    parser.add_argument("--dataset", required=True, help="the grasp dataset folder (batches.csv, objects.csv, grasps/)")
    parser.add_argument("--stability", required=True, help="stability.parquet of the stability_filter stage (stable objects; resting poses)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--shard", required=True, type=int, help="shard number, e.g. 000")
    parser.add_argument("--out", required=True, help="output grasp store (.zarr), read like a lift-validation shard")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.dataset.for_run import shard_dataset_grasps
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    grasps = shard_dataset_grasps(args.dataset, args.objects, args.stability, args.shard, config.shards, config.scene.table,
                                  config.hand)
    write_grasp_store(args.out, grasps, grasps.attrs)
    return 0
