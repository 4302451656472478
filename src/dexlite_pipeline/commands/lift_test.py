"""``dexlite lift-test GRASPS.zarr --out OUT.zarr [--objects DIR]``: MuJoCo lift test of every grasp in a store.

Writes the input grasps with ``lift_ratio``, ``lift_success``, ``failure_reason`` and
``initial_penetration_mm`` (plus the six-direction arrays with ``--six-directions``) and
prints a summary. Grasps with a non-finite pose or scale, or whose object is not among the
assets, are kept and flagged (``failure_reason = 'invalid_grasp: ...'``); the others are
simulated. ``--objects`` defaults to the ``objects/`` folder beside the store (a ``dexlite grasp``
output folder). Exit status 2 when no --objects folder holds prepared objects, 1 when the
store has grasps but none of them could be simulated. Physical constants: ``LiftConfig`` defaults, the ``lift`` section of
``--config-json``, then the explicit options, in that order; all are recorded in the output.
"""

from __future__ import annotations

import argparse
import os
import sys

from dexlite_pipeline.commands import add_objects_argument, objects_dirs

def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grasps", help="grasp store (.zarr)")
    add_objects_argument(parser)
    parser.add_argument("--out", required=True, help="output grasp store (.zarr) with the lift results")
    parser.add_argument("--config-json", default="{}", help="config sections as JSON; its 'lift' section sets the constants")
    parser.add_argument("--six-directions", action="store_true", default=None, help="also run the six-direction disturbance test")
    parser.add_argument("--friction", type=float, default=None, help="override lift.friction")
    parser.add_argument("--object-mass-kg", type=float, default=None, help="override lift.object_mass_kg")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.config import parse_config_json
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.sim.config import lift_config_from
    from dexlite_pipeline.sim.results import format_summary, lift_test_store, nothing_simulated

    config = lift_config_from(
        parse_config_json(args.config_json),
        friction=args.friction,
        object_mass_kg=args.object_mass_kg,
        six_directions=args.six_directions,
    )
    result, summary = lift_test_store(args.grasps, objects_dirs(args), config, args.threads or os.cpu_count() or 1)
    write_grasp_store(args.out, result, {"stage": "lift_test", "source": str(args.grasps)})
    print(format_summary(summary, config), file=sys.stdout)
    return 1 if nothing_simulated(args.grasps, summary) else 0
