"""Stage ``loop_summary`` (one round): the round's table per training object (grasps, distinct grasps, candidates
kept and dropped per reason) and its row of the loop table (with CPU seconds and the held-out check), as JSON."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config section diversity (JSON)")
    parser.add_argument("--round", required=True, type=int, help="the loop round, 0, 1, ...")
    parser.add_argument("--grasps", required=True, help="the round's grasp set (.zarr)")
    parser.add_argument("--heldout", action="append", default=[], help="a validated shard of the round's held-out check (repeatable)")
    parser.add_argument("--cost", action="append", default=[], help="a store of the round's candidates whose job's CPU seconds count (repeatable)")
    parser.add_argument("--heldout-cost", action="append", default=[], help="a store of the held-out check whose job's CPU seconds count (repeatable)")
    parser.add_argument("--model", default=None, help="the round's model (its training's CPU seconds; none in round 0)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--stability", required=True, help="stability.parquet of the stability_filter stage")
    parser.add_argument("--table", required=True, help="output table per training object (.csv)")
    parser.add_argument("--row", required=True, help="output row of the loop table (.json)")


def run(args: argparse.Namespace) -> int:
    import json

    from dexlite_pipeline.atomic import atomic_path
    from dexlite_pipeline.loop.summary import round_summary
    from dexlite_pipeline.settings import stage_config

    table, row = round_summary(
        args.round, args.grasps, args.heldout, args.cost, args.heldout_cost, args.model, args.objects, args.stability,
        stage_config(args.config_json).diversity,
    )
    with atomic_path(args.table) as tmp:
        table.to_csv(tmp, index=False)
    with atomic_path(args.row) as tmp:
        tmp.write_text(json.dumps(row, indent=1, sort_keys=True) + "\n")
    return 0
