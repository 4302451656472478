"""``dexlite curate``: filter optimized (and imported DexGraspNet) grasps into training data.

Two steps, so that each shard is one job and the summary one small job:

- ``--step curate --shard K``: the curated store of the shard and its per-object summary
  CSV (``curation.shard.curate_shard``);
- ``--step aggregate``: the per-shard summaries merged into one CSV.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--step", choices=("curate", "aggregate"), required=True)
    parser.add_argument("--config-json", default="{}", help="config sections curate, scene, hand, and for imported grasps device, shards and energy, as JSON")
    parser.add_argument("--shard", type=int, default=None, help="curate: shard index (selects the imported objects of this shard)")
    parser.add_argument("--optimized-grasps", action="append", default=[], help="curate: optimized grasp store(s) of this shard (repeatable)")
    parser.add_argument("--imported", default=None, help="curate: imported DexGraspNet grasp store (all objects; this shard's are used)")
    parser.add_argument("--stability", action="append", default=[], help="curate: stability table(s) (.parquet, repeatable)")
    parser.add_argument("--objects", action="append", default=[], help="curate: prepared objects dir(s) with catalogs (repeatable)")
    parser.add_argument("--out", help="curate: curated grasp store; aggregate: merged summary CSV")
    parser.add_argument("--summary-out", help="curate: this shard's summary CSV")
    parser.add_argument("--summary", action="append", default=[], help="aggregate: per-shard summary CSVs")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.curation.shard import curate_shard, merge_summary_files
    from dexlite_pipeline.atomic import atomic_path
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.settings import stage_config

    if args.step == "aggregate":
        if not args.summary or not args.out:
            raise ValueError("--step aggregate needs --summary (one per shard) and --out")
        merged = merge_summary_files(args.summary)
        with atomic_path(args.out) as tmp:
            merged.to_csv(tmp, index=False)
        print(f"curation summary: {int(merged['n_kept'].sum())} of {int(merged['n_input'].sum())} grasps kept over {len(merged)} objects")
        return 0
    if args.shard is None or not args.out or not args.summary_out:
        raise ValueError("--step curate needs --shard, --out and --summary-out")
    if not args.optimized_grasps and not args.imported:
        raise ValueError("--step curate needs --optimized-grasps and/or --imported")
    config = stage_config(args.config_json)
    kept, attrs, summary = curate_shard(
        args.optimized_grasps, args.imported, args.stability, args.objects, args.shard, shards=config.shards, curate=config.curate,
        energy=config.energy, scene=config.scene, device=config.device, threads=args.threads or 1, hand=config.hand,
    )
    write_grasp_store(args.out, kept, attrs)
    with atomic_path(args.summary_out) as tmp:
        summary.to_csv(tmp, index=False)
    dropped = ", ".join(f"{r} {c}" for r, c in attrs["dropped"].items() if c)
    print(f"shard {args.shard}: kept {len(kept)} of {attrs['n_input']} grasps; dropped: {dropped or 'none'}")
    for reason, count in attrs["force_closure_failures"].items():
        print(f"shard {args.shard}: {count} grasps dropped as force_closure_unknown: {reason}")
    return 0
