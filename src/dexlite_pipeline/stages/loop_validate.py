"""Stage ``loop_validate`` (one round, part and shard): the equal energy filter, the lift test and the
six-direction test of a round's refined grasps, each grasp with the reason it is not kept (``drop_reason``).

On each object's table in tabletop mode (resting poses from ``--stability``), with the hand of config key ``hand`` (its
contact candidates, its lift-test scene; the grasps must be of it). Part ``heldout`` lift-tests every
refined grasp (success per attempt, as the evaluation counts it); part ``train`` only those the filter passed.
"""

from __future__ import annotations

import argparse

from dexlite_pipeline.loop.stage_options import add_round_shard_arguments


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--grasps", required=True, help="the round's refined grasp shard (loop_post_optimize output)")
    add_round_shard_arguments(parser, "device, hand, curate.thresholds, energy.weights, lift, scene and loop.six_directions", "validated grasp store (.zarr)")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.hand.choice import SHADOW, resolve_hand
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.loop.round_basics import HELDOUT, process_cpu_seconds
    from dexlite_pipeline.loop.validate_round import validate_round
    from dexlite_pipeline.settings import stage_config
    from dexlite_pipeline.tabletop import load_support_planes

    config = stage_config(args.config_json)
    planes = load_support_planes(config.scene.table, args.stability)
    hand = None if config.hand == SHADOW else resolve_hand(config.hand, resolve_device(config.device))  # None: the Shadow Hand, as before
    validated = validate_round(
        args.grasps, args.objects, config.curate.thresholds, config.energy.weights, config.lift, config.loop.six_directions,
        args.threads or 1, planes, str(resolve_device(config.device)), simulate_all=args.part == HELDOUT, hand=hand, hand_name=config.hand,
    )
    write_grasp_store(args.out, validated, {"cpu_seconds": process_cpu_seconds()})
    return 0
