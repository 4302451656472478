"""Stage ``sample_grasps`` (one shard): CVAE grasps for the shard's stable objects.

Held-out objects get pure synthesis (``cvae_raw``), training objects dataset expansion and
the learning ladder's rows (``model.sample_shard``); with a trained evaluator (``--evaluator``) also the
best-scored distinct syntheses of a larger pool on held-out objects (``cvae_ranked``, ``evaluator.ranking``). The model
and the evaluator must be of config key ``hand`` (each refused in one line otherwise).
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, device, shards, hand, sample (and with --evaluator: evaluator, diversity, scene, evaluate) (canonical JSON)")
    parser.add_argument("--model", default=None, help="trained model (cvae.pt; default: the shipped model of the config's hand, e.g. src/dexlite_pipeline/data/shadow-hand-household/cvae.pt)")
    parser.add_argument("--shipped-model", default=None, help="pretrained model also sampled on held-out objects it never trained on "
                        "(rows shipped_raw; default: sample.shipped_model, \"\" = none)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--stability", required=True, help="stability.parquet of the stability_filter stage")
    parser.add_argument("--lift", action="append", default=[], help="lift-validated grasp shard, the grasps to expand (repeatable)")
    parser.add_argument("--evaluator", default=None, help="trained grasp evaluator (train_evaluator's evaluator.pt): also rank pooled syntheses "
                        "on held-out objects (rows cvae_ranked) and score the unranked ones; needs config sections evaluator, diversity, scene")
    parser.add_argument("--shard", required=True, type=int, help="shard number, e.g. 000")
    parser.add_argument("--out", required=True, help="output grasp store (.zarr)")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.model.sample_shard import sample_shard
    from dexlite_pipeline.model.shipped import model_or_shipped
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    shipped = args.shipped_model if args.shipped_model is not None else config.sample.shipped_model
    grasps, attrs = sample_shard(
        str(model_or_shipped(args.model, config.hand)), args.objects, args.stability, args.lift, args.shard, shards=config.shards, sample=config.sample,
        seed=config.seed, device=config.device, shipped_model=shipped or None, hand=config.hand,
        table=config.scene.table,
    )
    if args.evaluator:
        from dexlite_pipeline.evaluator.ranking import rank_shard

        grasps, attrs["ranking"] = rank_shard(
            grasps, str(model_or_shipped(args.model, config.hand)), args.evaluator, args.objects, args.stability, args.shard, shards=config.shards,
            sample=config.sample, section=config.evaluator, diversity=config.diversity, table=config.scene.table, seed=config.seed,
            device=config.device, hand=config.hand, evaluated_per_object=config.evaluate.grasps_per_object,
        )
    write_grasp_store(args.out, grasps, attrs)
    return 0
