"""``dexlite energy GRASPS.zarr --objects DIR --out OUT.zarr``: per-grasp energy terms of any grasp store.

Writes the input grasps with E_fc, E_dis, E_pen, E_spen, E_joints, E_total,
penetration_mm, contact_distance_mm, contact_index, passes_energy_thresholds and
energy_failure_reason added (existing arrays of those names are replaced), and prints
a summary. Contacts: a ``contact_index`` array in the input is used; otherwise the four
pad points nearest the object surface, or with ``--contact-samples N`` the best of N
searched sets (``energy.per_grasp.store_energies``).
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grasps", help="input grasp store (.zarr)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir (repeatable)")
    parser.add_argument("--out", required=True, help="output grasp store (.zarr)")
    parser.add_argument("--config", default=None, help="config.yaml to take the energy section from (default: built-in weights)")
    parser.add_argument("--device", default="auto", help="auto, cpu, cuda, cuda:N")
    parser.add_argument("--batch-size", type=int, default=256, help="grasps per energy evaluation")
    parser.add_argument("--contact-samples", type=int, default=0,
                        help="without stored contacts: also search this many contact sets for the lowest E_fc + 100 E_dis (0: the 4 pads nearest the surface)")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.config import load_config
    from dexlite_pipeline.energy.per_grasp import energy_summary_lines, store_energies
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.settings import build_config

    config = build_config(load_config(args.config) if args.config else {}, args.config or "defaults")
    grasps, attrs = store_energies(
        args.grasps, args.objects, config.energy, config.seed_grasps.thresholds, args.device, args.batch_size, args.contact_samples
    )
    write_grasp_store(args.out, grasps, attrs)
    for line in energy_summary_lines(grasps.arrays):
        print(line)
    print(f"wrote {args.out}")
    return 0
