"""Stage ``model_batch`` (one shard): a dataset batch made by the model, optimization from scratch topping up.

Reads the prepared objects and the stability table, writes ``--out`` (grasp store): every grasp tested, held or
not, with its lift and six-direction outcome and its ``source`` (``model`` or ``optimization``); the attributes
record the sections used, the model and evaluator files (SHA-256), the objects topped up and the phases' seconds
(``tools.model_batch``) and the hand (config key ``hand``: ``hand``, ``joint_names``; poses of 6 + J numbers).
``dexlite dataset-add`` adds the run as a batch of kind ``model`` to a dataset of that hand. Exit status 2 with one
line when a ``model_batch`` key names a missing file or a model or evaluator of another hand, or ``hand`` an unusable one.
"""

from __future__ import annotations

import argparse
import logging

log = logging.getLogger("dexlite.model_batch")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, device, shards, hand, scene, model_batch, sample, "
                        "post_optimize, evaluator, optimize_grasps, energy, diversity, lift (canonical JSON)")
    parser.add_argument("--shard", required=True, type=int, help="shard number, e.g. 000")
    parser.add_argument("--stability", required=True, help="stability table (.parquet)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--out", required=True, help="output grasp store (.zarr)")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.settings import stage_config
    from dexlite_pipeline.tools.model_batch import model_batch_shard

    config = stage_config(args.config_json)
    grasps, attrs = model_batch_shard(args.objects, args.stability, args.shard, config, args.threads or 1)  # ModelBatchError: one line, exit 2
    write_grasp_store(args.out, grasps, attrs)
    held = int(grasps.arrays["lift_success"].sum()) if len(grasps) else 0
    distinct = sum(attrs["distinct_held_per_object"].values())
    log.info("shard %03d: %d grasps tested on %d objects, %d held, %d distinct held; %d object(s) topped up -> %s", args.shard, len(grasps),
             len(attrs["objects"]), held, distinct, len(attrs["topped_up_objects"]), args.out)
    return 0
