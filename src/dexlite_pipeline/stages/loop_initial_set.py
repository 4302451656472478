"""Stage ``loop_initial_set``: round 0's grasp set, the lift-successful grasps of training objects the first model trains on."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--lift", action="append", required=True, help="a lift-validated grasp shard (repeatable)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--out", required=True, help="round 0's grasp set (.zarr)")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.loop.initial_set import initial_set

    write_grasp_store(args.out, initial_set(args.lift, args.objects), {"stage": "loop_initial_set", "round": 0, "sources": args.lift})
    return 0
