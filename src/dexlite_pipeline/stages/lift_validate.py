"""Stage ``lift_validate`` (one shard): lift-test the curated grasps of a shard.

Reads ``results/curate/shard_{shard}.zarr`` and writes ``results/lift/shard_{shard}.zarr``:
every curated grasp with ``lift_ratio``, ``lift_success``, ``failure_reason`` (and the
six-direction arrays when ``lift.six_directions`` is on); the constants and a summary
are stored in the attributes. Later stages train only on ``lift_success``. In tabletop mode
(``scene.table``) each object rests on its table (from ``--stability``) and every grasp records
its support plane (``support_normal``, ``support_offset_m``) and ``table_depth_mm``. The hand is config key ``hand``
(``hand.choice``): the curated store must be of it, and a hand from its MJCF is simulated from its own file and servos.
"""

from __future__ import annotations

import argparse
import logging

log = logging.getLogger("dexlite.lift_validate")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, hand, lift and scene (canonical JSON)")
    parser.add_argument("--grasps", required=True, help="curated grasp shard (curate output)")
    parser.add_argument("--stability", help="stability table with the objects' resting poses (needed in tabletop mode, scene.table)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir (repeatable)")
    parser.add_argument("--shard", required=True, help="shard id, e.g. 000")
    parser.add_argument("--out", required=True, help="lift-validated grasp store (.zarr)")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.settings import stage_config
    from dexlite_pipeline.sim.results import format_summary, lift_test_store, nothing_simulated

    from dexlite_pipeline.tabletop import load_support_planes, store_attrs

    from dexlite_pipeline.hand.choice import hand_record, resolve_hand

    settings = stage_config(args.config_json)
    config = settings.lift
    record = hand_record(settings.hand)  # an unusable hand: one line before any work
    planes = load_support_planes(settings.scene.table, args.stability)
    result, summary = lift_test_store(args.grasps, args.objects, config, args.threads or 1, support_planes=planes,
                                      hand=resolve_hand(settings.hand, "cpu"), hand_record=record)
    attrs = {"stage": "lift_validate", "shard": args.shard, "source": str(args.grasps), **record,
             "config": {"seed": settings.seed, "lift": config.as_dict()}}
    if planes is not None:
        attrs["config"]["scene"] = {"table": True}
        attrs.update(store_attrs(True))
    write_grasp_store(args.out, result, attrs)
    for line in format_summary(summary, config).splitlines():
        log.info("shard %s: %s", args.shard, line)
    return 1 if nothing_simulated(args.grasps, summary) else 0
