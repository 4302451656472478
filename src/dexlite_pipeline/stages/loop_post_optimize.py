"""Stage ``loop_post_optimize`` (one round, part and shard): refine a round's sampled grasps.

The pipeline's post-optimization (``optim.post_shard``) as the ``post_optimize`` stage runs it, on each
object's table in tabletop mode, without the random-start baseline, from a random stream of the round's own; the
training part for ``loop.post_iterations`` steps when set (``loop.post_optimize_round.round_post_optimize_config``), with
the model of config key ``hand`` (the samples must be of it).
"""

from __future__ import annotations

import argparse

from dexlite_pipeline.loop.stage_options import add_round_shard_arguments


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--sample", required=True, help="the round's sampled grasp shard (loop_sample output)")
    add_round_shard_arguments(parser, "seed, device, hand, post_optimize, scene, energy.self_penetration_margin_m and loop.post_iterations", "refined grasp store (.zarr)")


def run(args: argparse.Namespace) -> int:
    import dataclasses

    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.loop.post_optimize_round import round_post_optimize_config
    from dexlite_pipeline.loop.round_basics import process_cpu_seconds, round_seed
    from dexlite_pipeline.optim.post_shard import post_optimize_shard
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    config = dataclasses.replace(
        config, seed=round_seed(config.seed, args.round, 0, args.part), post_optimize=round_post_optimize_config(config.post_optimize, config.loop, args.part)
    )
    (refined, attrs), _ = post_optimize_shard(
        args.sample, args.objects, args.shard, post_optimize=config.post_optimize,
        self_penetration_margin_m=config.energy.self_penetration_margin_m, scene=config.scene, seed=config.seed, device=config.device,
        stability_path=args.stability, hand=config.hand,
    )
    write_grasp_store(args.out, refined, {**attrs, "round": args.round, "part": args.part, "cpu_seconds": process_cpu_seconds()})
    return 0
