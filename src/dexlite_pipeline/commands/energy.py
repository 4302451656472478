"""``dexlite energy GRASPS.zarr --out OUT.zarr [--objects DIR]``: per-grasp energy terms of any grasp store.

Writes the input grasps with E_fc, E_dis, E_pen, E_spen, E_joints, E_total,
penetration_mm, contact_distance_mm, contact_index, passes_energy_thresholds and
energy_failure_reason added (existing arrays of those names are replaced), and prints
a summary. Contacts: a ``contact_index`` array in the input is used; otherwise the four
pad points nearest the object surface, or with ``--contact-samples N`` the best of N
searched sets (``energy.per_grasp.store_energies``). ``--objects`` defaults to the ``objects/``
folder beside the store (a ``dexlite grasp`` output folder); ``--config-json`` takes the
``energy`` and ``optimize_grasps.thresholds`` sections, like the other commands' option. The terms are those
of the hand the store records (its poses, collision shapes and contact candidates; the Shadow Hand for a store
without one); a hand file changed since the store was written is refused in one line.
"""

from __future__ import annotations

import argparse

from dexlite_pipeline.commands import add_objects_argument, objects_dirs, store_hand_model


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grasps", help="input grasp store (.zarr)")
    add_objects_argument(parser)
    parser.add_argument("--out", required=True, help="output grasp store (.zarr)")
    parser.add_argument("--config-json", default="{}",
                        help="config sections (energy, optimize_grasps.thresholds) as inline JSON or a .json/.yaml file such as config.yaml (default: built-in values)")
    parser.add_argument("--device", default="auto", help="auto, cpu, cuda, cuda:N")
    parser.add_argument("--batch-size", type=int, default=256, help="grasps per energy evaluation")
    parser.add_argument("--contact-samples", type=int, default=0,
                        help="without stored contacts: also search this many contact sets for the lowest E_fc + 100 E_dis (0: the 4 pads nearest the surface)")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.energy.per_grasp import energy_summary_lines, store_energies
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    objects = objects_dirs(args)
    device = resolve_device(args.device)
    hand, _ = store_hand_model(args.grasps, device)  # the store's own hand (a changed hand file: one line)
    grasps, attrs = store_energies(
        args.grasps, objects, config.energy, config.optimize_grasps.thresholds, device, args.batch_size, args.contact_samples, hand
    )
    write_grasp_store(args.out, grasps, attrs)
    for line in energy_summary_lines(grasps.arrays):
        print(line)
    print(f"wrote {args.out}")
    return 0
