"""Stage ``loop_sample`` (one round, part and shard): grasps from a model for the data loop.

Part ``train``: round r's candidates, sampled by round r-1's model on every stable training object of the
shard with the loop's associated points (``loop.anchor_rule``); part ``heldout``: round r's model on the held-out objects, the
round's small held-out check (``loop.sample_round.sample_round``). The model (and the evaluator) must be of config key
``hand``: each is refused in one line otherwise.
"""

from __future__ import annotations

import argparse

from dexlite_pipeline.loop.stage_options import add_round_shard_arguments


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--model", required=True, help="the model to sample from (cvae.pt)")
    parser.add_argument("--evaluator", default=None, help="part train with loop.rank_candidates: the learned evaluator (evaluator.pt) that "
                        "keeps the best distinct of evaluator.pool_factor x more candidates (config sections evaluator, diversity, scene)")
    add_round_shard_arguments(parser, "seed, device, shards, hand, sample and loop", "output grasp store (.zarr)")


def run(args: argparse.Namespace) -> int:
    import dataclasses

    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.loop.round_basics import TRAIN
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.loop.round_basics import process_cpu_seconds
    from dexlite_pipeline.loop.sample_round import sample_round
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    ranking = args.evaluator and args.part == TRAIN
    loop = dataclasses.replace(config.loop, grasps_per_object=config.loop.grasps_per_object * config.evaluator.pool_factor) if ranking else config.loop
    grasps, attrs = sample_round(
        args.model, args.objects, args.stability, args.shard, config.shards, args.part, args.round, loop, config.sample,
        resolve_device(config.device), config.seed, config.hand, config.scene.table,
    )
    if ranking:
        from dexlite_pipeline.evaluator.ranking import rank_candidates

        grasps, attrs["ranking"] = rank_candidates(grasps, args.evaluator, args.objects, args.stability, config.loop.grasps_per_object,
                                                   config.diversity, config.scene.table, config.device, config.hand)
    write_grasp_store(args.out, grasps, {**attrs, "cpu_seconds": process_cpu_seconds()})
    return 0
