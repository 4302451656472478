"""Stage ``loop_train`` (one round): round r's model, round r-1's trained on for ``loop.train_steps`` more steps
on round r's grasp set (``model.trainer``, warm start, ``loop.train_round.round_training_config``); the same files as
``train_cvae``. The set and the model must be of config key ``hand`` (refused in one line otherwise)."""

from __future__ import annotations

import argparse
import logging

from dexlite_pipeline.model.stage_options import add_training_state_arguments, training_state_path

log = logging.getLogger("dexlite.loop_train")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, device, hand, train, scene, energy.self_penetration_margin_m and loop (JSON)")
    parser.add_argument("--grasps", required=True, help="the round's grasp set (loop_merge output)")
    parser.add_argument("--initial-model", required=True, help="round r-1's model (cvae.pt), trained on from where it is")
    parser.add_argument("--stability", help="stability table with the objects' resting poses (needed in tabletop mode, scene.table)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--round", required=True, type=int, help="the loop round, 1, 2, ...")
    parser.add_argument("--model", required=True, help="output model file (cvae.pt)")
    parser.add_argument("--history", required=True, help="output per-epoch loss table (.csv)")
    parser.add_argument("--curves", required=True, help="output plot of the loss curves (.png)")
    add_training_state_arguments(parser)


def run(args: argparse.Namespace) -> int:
    import dataclasses

    from dexlite_pipeline.loop.round_basics import process_cpu_seconds, round_seed
    from dexlite_pipeline.loop.train_round import round_training_config
    from dexlite_pipeline.model.trainer import train_from_lift_shards, write_trained_model
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    state_path = training_state_path(args)
    config = dataclasses.replace(config, seed=round_seed(config.train.training_seed(config.seed), args.round), train=round_training_config(config.train, config.loop))
    trained = train_from_lift_shards(
        [args.grasps], args.objects, train=config.train, self_penetration_margin_m=config.energy.self_penetration_margin_m,
        table=config.scene.table, seed=config.seed, device=config.device, stability_path=args.stability, initial_model_path=args.initial_model,
        hand=config.hand, state_path=state_path, state_every_s=args.state_every_s,
    )
    trained.facts.update(loop_round=args.round, initial_model=args.initial_model, cpu_seconds=process_cpu_seconds())
    write_trained_model(trained, args.model, args.history, args.curves)
    if state_path is not None:
        state_path.unlink(missing_ok=True)  # the model it led to is written
    log.info("round %d: wrote %s (%d steps from %s, %d training grasps of %d objects)", args.round, args.model, trained.facts["steps"],
             args.initial_model, trained.facts["train_grasps"], len(trained.facts["train_object_ids"]))
    return 0
