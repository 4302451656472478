"""``dexlite lift-test GRASPS.zarr --objects DIR --out OUT.zarr``: MuJoCo lift test of every grasp in a store.

Writes the input grasps with ``lift_ratio``, ``lift_success``, ``failure_reason`` and
``initial_penetration_mm`` (plus the six-direction arrays with ``--six-directions``) and
prints a summary. Grasps with a non-finite pose or scale, or whose object is not among the
assets, are kept and flagged (``failure_reason = 'invalid_grasp: ...'``); the others are
simulated. Exit status 2 when no --objects folder holds prepared objects, 1 when the
store has grasps but none of them could be simulated. Physical constants: ``LiftConfig`` defaults, the ``lift`` section of
``--config-json``, then the explicit options, in that order; all are recorded in the output.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from pathlib import Path

log = logging.getLogger("dexlite.lift_test")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grasps", help="grasp store (.zarr)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir (repeatable)")
    parser.add_argument("--out", required=True, help="output grasp store (.zarr) with the lift results")
    parser.add_argument("--config-json", default="{}", help="config sections as JSON; its 'lift' section sets the constants")
    parser.add_argument("--six-directions", action="store_true", default=None, help="also run the six-direction disturbance test")
    parser.add_argument("--friction", type=float, default=None, help="override lift.friction")
    parser.add_argument("--object-mass-kg", type=float, default=None, help="override lift.object_mass_kg")


def check_objects_dirs(dirs: list[str]) -> None:
    """Every --objects folder must exist and one at least hold prepared objects (an id missing from them is flagged per grasp)."""
    from dexlite_pipeline.objects.assets import ASSETS_DIR, available_object_ids

    for d in dirs:
        if not Path(d).is_dir():
            raise FileNotFoundError(f"{d}: objects folder not found")
    if not available_object_ids(dirs):
        raise FileNotFoundError(
            f"{', '.join(map(str, dirs))}: no prepared objects (expected {ASSETS_DIR}/<object id>/ as written by prepare-objects)"
        )


def nothing_simulated(grasps_path: str, summary: dict) -> bool:
    """True (and an error line) when the store had grasps but none could be simulated."""
    if summary["n_grasps"] and not summary["n_simulated"]:
        log.error("%s: none of the %d grasps could be simulated (see the reasons above)", grasps_path, summary["n_grasps"])
        return True
    return False


def report_invalid(grasps_path: str, failure_reason) -> None:
    """One warning line per kind of invalid grasp, so a user sees what was not simulated."""
    from collections import Counter

    counts = Counter(r for r in failure_reason if str(r).startswith("invalid_grasp"))
    for reason, count in sorted(counts.items()):
        log.warning("%s: %d grasp(s) not simulated: %s", grasps_path, count, reason)


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.config import parse_config_json
    from dexlite_pipeline.io.grasp_store import read_grasp_store, write_grasp_store
    from dexlite_pipeline.sim.config import lift_config_from
    from dexlite_pipeline.sim.results import format_summary, lift_grasp_set

    config = lift_config_from(
        parse_config_json(args.config_json),
        friction=args.friction,
        object_mass_kg=args.object_mass_kg,
        six_directions=args.six_directions,
    )
    check_objects_dirs(args.objects)
    grasps = read_grasp_store(args.grasps)
    threads = args.threads or os.cpu_count() or 1
    result, summary = lift_grasp_set(grasps, args.objects, config, threads)
    report_invalid(args.grasps, result.arrays["failure_reason"])
    write_grasp_store(args.out, result, {"stage": "lift_test", "source": str(args.grasps)})
    print(format_summary(summary, config), file=sys.stdout)
    return 1 if nothing_simulated(args.grasps, summary) else 0
