"""Stage ``sample_grasps`` (one shard): CVAE grasps for the shard's stable objects.

Held-out objects get pure synthesis (``cvae_raw``), training objects dataset expansion and
the learning ladder's rows (``model.sample_shard``).
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, device, shards, sample (canonical JSON)")
    parser.add_argument("--model", required=True, help="trained model (cvae.pt)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--stability", required=True, help="stability.parquet of the stability_filter stage")
    parser.add_argument("--lift", action="append", default=[], help="lift-validated grasp shard, the expansion seeds (repeatable)")
    parser.add_argument("--shard", required=True, type=int, help="shard number, e.g. 000")
    parser.add_argument("--out", required=True, help="output grasp store (.zarr)")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.model.sample_shard import sample_shard
    from dexlite_pipeline.settings import stage_config

    grasps, attrs = sample_shard(args.model, args.objects, args.stability, args.lift, args.shard, stage_config(args.config_json))
    write_grasp_store(args.out, grasps, attrs)
    return 0
