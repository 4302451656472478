"""``dexlite lift-test GRASPS.zarr --out OUT.zarr [--objects DIR]``: MuJoCo lift test of every grasp in a store.

Writes the input grasps with ``lift_ratio``, ``lift_success``, ``failure_reason`` and
``initial_penetration_mm`` (plus the six-direction arrays with ``--six-directions``) and
prints a summary. Grasps with a non-finite pose or scale, or whose object is not among the
assets, are kept and flagged (``failure_reason = 'invalid_grasp: ...'``); the others are
simulated. ``--objects`` defaults to the ``objects/`` folder beside the store (a ``dexlite grasp``
output folder). Exit status 2 when no --objects folder holds prepared objects, 1 when the
store has grasps but none of them could be simulated. Physical constants: ``LiftConfig`` defaults, the ``lift`` section of
``--config-json``, then the explicit options, in that order; all are recorded in the output.
Tables: a store written in tabletop mode records each grasp's support plane, and the test then
puts each object on that table (docs/design.md, "Tabletop mode"); ``--stability`` takes the
resting poses of a stability table instead, ``--floating`` tests without a table. The summary
says which.
"""

from __future__ import annotations

import argparse
import os
import sys

from dexlite_pipeline.commands import add_objects_argument, objects_dirs, store_hand_model

def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grasps", help="grasp store (.zarr)")
    add_objects_argument(parser)
    parser.add_argument("--out", required=True, help="output grasp store (.zarr) with the lift results")
    parser.add_argument("--config-json", default="{}", help="config sections as JSON; its 'lift' section sets the constants")
    parser.add_argument("--six-directions", action="store_true", default=None, help="also run the six-direction disturbance test")
    parser.add_argument("--friction", type=float, default=None, help="override lift.friction")
    parser.add_argument("--object-mass-kg", type=float, default=None, help="override lift.object_mass_kg")
    table = parser.add_mutually_exclusive_group()
    table.add_argument("--stability", default=None, help="stability table: each object on the table of its resting pose")
    table.add_argument("--floating", action="store_true", help="no table, even if the store recorded one")


def lift_test_tables(grasps_path: str, stability: str | None, floating: bool):
    """(support planes or None, a phrase saying where the objects are) for the lift test of a store."""
    from dexlite_pipeline.io.grasp_store import read_grasp_store
    from dexlite_pipeline.tabletop import SupportPlanes, planes_from_store

    if floating:
        return None, "floating (--floating), gravity along each object frame's -z"
    if stability:
        return SupportPlanes.from_stability_table(stability), f"on the tables of their resting poses ({stability})"
    stored = planes_from_store(read_grasp_store(grasps_path))
    if stored is None:
        return None, "floating (the store records no table), gravity along each object frame's -z"
    return stored, "on the tables recorded in the grasp store"


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.config import parse_config_json
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.sim.config import lift_config_from
    from dexlite_pipeline.sim.results import check_objects_dirs, format_summary, lift_test_store, nothing_simulated

    config = lift_config_from(
        parse_config_json(args.config_json),
        friction=args.friction,
        object_mass_kg=args.object_mass_kg,
        six_directions=args.six_directions,
    )
    objects = objects_dirs(args)
    check_objects_dirs(objects)  # before reading the store: the errors come in the order users fix them
    planes, where = lift_test_tables(args.grasps, args.stability, args.floating)
    hand, record = store_hand_model(args.grasps)
    result, summary = lift_test_store(args.grasps, objects, config, args.threads or os.cpu_count() or 1, support_planes=planes, hand=hand,
                                      hand_record=record)
    write_grasp_store(args.out, result, {"stage": "lift_test", "source": str(args.grasps), "scene": {"table": planes is not None}})
    print(f"objects: {where}", file=sys.stdout)
    print(format_summary(summary, config), file=sys.stdout)
    return 1 if nothing_simulated(args.grasps, summary) else 0
