"""Stage ``loop_merge`` (one round): round r's grasp set, round r-1's plus the round's validated grasps that are
new distinct grasps (``loop.merge.merge_round``); the candidates per object and reason go in its attributes. The stores
must be of config key ``hand`` (refused in one line otherwise), which the set records."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections diversity and hand (JSON; hand absent: the Shadow Hand)")
    parser.add_argument("--previous", required=True, help="round r-1's grasp set (.zarr)")
    parser.add_argument("--validated", action="append", required=True, help="a validated shard of the round's candidates (repeatable)")
    parser.add_argument("--round", required=True, type=int, help="the loop round, 1, 2, ...")
    parser.add_argument("--out", required=True, help="round r's grasp set (.zarr)")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.loop.merge import merge_round_stores
    from dexlite_pipeline.loop.round_basics import process_cpu_seconds
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    merged, attrs = merge_round_stores(args.previous, args.validated, config.diversity, args.round, config.hand)
    write_grasp_store(args.out, merged, {**attrs, "cpu_seconds": process_cpu_seconds()})
    return 0
