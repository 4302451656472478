"""Stage ``post_optimize`` (one shard): refine the CVAE's grasps by annealed steps on E_post.

Writes ``--out`` with the refined pose (``hand_pose``) beside the sampled one
(``raw_hand_pose``), every energy term before (``raw_E_*``) and after (``E_*``), and the
per-iteration traces (``trace_E_post`` etc., attribute ``trace_iterations``). With
``post_optimize.random_baseline`` it also writes ``--random-out``: the same optimization
from random convex-hull starts for the same held-out objects and scales as the shard's
pure syntheses (``cvae_raw``), the baseline for "CVAE starts converge faster"
(``optim.post_shard``). In tabletop mode (``scene.table``) E_post includes E_table,
starts below the table are raised above it first, random starts come from above it, and
every row records its support plane (resting poses from ``--stability``). E_post uses the model of config key ``hand``;
the sampled store must be of it.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, device, hand, post_optimize, scene and energy.self_penetration_margin_m (JSON)")
    parser.add_argument("--stability", help="stability table with the objects' resting poses (needed in tabletop mode, scene.table)")
    parser.add_argument("--sample", required=True, help="sampled grasp shard (sample_grasps output)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir (repeatable)")
    parser.add_argument("--shard", required=True, type=int, help="shard number, e.g. 000")
    parser.add_argument("--out", required=True, help="refined grasp store (.zarr)")
    parser.add_argument("--random-out", required=True, help="random-init baseline store (.zarr; no rows when post_optimize.random_baseline is off)")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.optim.post_shard import post_optimize_shard
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    (refined, attrs), (baseline, baseline_attrs) = post_optimize_shard(
        args.sample, args.objects, args.shard, post_optimize=config.post_optimize,
        self_penetration_margin_m=config.energy.self_penetration_margin_m, scene=config.scene, seed=config.seed, device=config.device,
        stability_path=args.stability, hand=config.hand,
    )
    write_grasp_store(args.out, refined, attrs)
    write_grasp_store(args.random_out, baseline, baseline_attrs)
    return 0
