"""Stage ``train_cvae``: train the PointNet + CVAE on lift-validated grasps of training objects.

Writes ``--model`` (state dict + configs, loads with ``torch.load(weights_only=True)``),
``--history`` (every loss term per epoch, train and validation) and ``--curves`` (their
plot); progress per epoch goes to the log (``model.trainer``). The model is for config key ``hand`` (the lift shards
must be of it; its file records it).
"""

from __future__ import annotations

import argparse
import logging

from dexlite_pipeline.model.stage_options import add_training_state_arguments, training_state_path

log = logging.getLogger("dexlite.train_cvae")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, device, hand, train, scene and energy.self_penetration_margin_m (JSON)")
    parser.add_argument("--stability", help="stability table with the objects' resting poses (needed in tabletop mode, scene.table)")
    parser.add_argument("--lift", action="append", required=True, help="a lift-validated grasp shard (repeatable)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--model", required=True, help="output model file (cvae.pt)")
    parser.add_argument("--history", required=True, help="output per-epoch loss table (.csv)")
    parser.add_argument("--curves", required=True, help="output plot of the loss curves (.png)")
    add_training_state_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.model.trainer import train_from_lift_shards, write_trained_model
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    state_path = training_state_path(args)
    trained = train_from_lift_shards(
        args.lift, args.objects, train=config.train, self_penetration_margin_m=config.energy.self_penetration_margin_m,
        table=config.scene.table, seed=config.train.training_seed(config.seed), device=config.device, stability_path=args.stability,
        hand=config.hand, state_path=state_path, state_every_s=args.state_every_s,
    )
    write_trained_model(trained, args.model, args.history, args.curves)
    if state_path is not None:
        state_path.unlink(missing_ok=True)  # the model it led to is written
    log.info("wrote %s (%d steps, %d training grasps of %d objects)", args.model, trained.facts["steps"],
             trained.facts["train_grasps"], len(trained.facts["train_object_ids"]))
    return 0
