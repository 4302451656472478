"""Stage ``evaluator_examples`` (one shard): the trained model's syntheses on the shard's training objects,
post-optimized and simulated, every one: the learned evaluator's on-generator examples (``evaluator.examples``)."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, device, shards, hand, sample, post_optimize, scene, curate, "
                        "energy, lift and evaluator (JSON)")
    parser.add_argument("--model", required=True, help="the trained model (train_cvae's cvae.pt)")
    parser.add_argument("--stability", required=True, help="stability.parquet of the stability_filter stage (stable objects; resting poses)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--shard", required=True, type=int, help="shard number, e.g. 000")
    parser.add_argument("--out", required=True, help="output simulated grasp store (.zarr)")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.evaluator.examples import collect_examples
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.loop.round_basics import process_cpu_seconds
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    examples = collect_examples(args.model, args.objects, args.stability, args.shard, config, args.threads or 1)
    write_grasp_store(args.out, examples, {**examples.attrs, "cpu_seconds": process_cpu_seconds()})
    return 0
