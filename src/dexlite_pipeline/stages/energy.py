"""``dexlite energy GRASPS.zarr --objects DIR --out OUT.zarr``: per-grasp energy terms of any grasp store.

Writes the input grasps with E_fc, E_dis, E_pen, E_spen, E_joints, E_total,
penetration_mm, contact_distance_mm, contact_index, passes_energy_thresholds and
energy_failure_reason added (existing arrays of those names are replaced), and prints
a summary. Contacts: a ``contact_index`` array in the input is used; otherwise the four
pad points nearest the object surface, or with ``--contact-samples N`` the best of N
searched sets (see ``energy.evaluate_grasp_energies``).
"""

from __future__ import annotations

import argparse
import dataclasses
import logging

import numpy as np

log = logging.getLogger("dexlite.energy")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grasps", help="input grasp store (.zarr)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir (repeatable)")
    parser.add_argument("--out", required=True, help="output grasp store (.zarr)")
    parser.add_argument("--config", default=None, help="config.yaml to take the energy section from (default: built-in weights)")
    parser.add_argument("--device", default="auto", help="auto, cpu, cuda, cuda:N")
    parser.add_argument("--batch-size", type=int, default=256, help="grasps per energy evaluation")
    parser.add_argument("--contact-samples", type=int, default=0,
                        help="without stored contacts: also search this many contact sets for the lowest E_fc + 100 E_dis (0: the 4 pads nearest the surface)")


def summary_lines(arrays: dict[str, np.ndarray]) -> list[str]:
    """Human-readable medians and the threshold pass fraction over the evaluated grasps."""
    evaluated = arrays["energy_failure_reason"] == ""
    lines = [f"grasps: {len(evaluated)}, evaluated: {int(evaluated.sum())}"]
    if evaluated.any():
        for name in ("E_fc", "E_dis", "E_pen", "E_spen", "E_joints", "penetration_mm", "contact_distance_mm"):
            values = arrays[name][evaluated]
            lines.append(f"{name:>20}: median {np.median(values):.4g}  p90 {np.percentile(values, 90):.4g}")
        lines.append(f"pass energy thresholds: {100 * arrays['passes_energy_thresholds'][evaluated].mean():.1f}%")
    return lines


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.config import from_section, load_config
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.energy import EnergyConfig, evaluate_grasp_energies
    from dexlite_pipeline.io.grasp_store import read_grasp_store, write_grasp_store
    from dexlite_pipeline.optim.seed import EnergyThresholds, SeedConfig

    if args.batch_size < 1:
        raise ValueError(f"--batch-size must be positive, got {args.batch_size}")
    config = load_config(args.config) if args.config else {}
    energy_config = from_section(EnergyConfig, config.get("energy"), "config.energy")
    thresholds = from_section(SeedConfig, config.get("seed_grasps"), "config.seed_grasps").thresholds if config else EnergyThresholds()
    grasps = read_grasp_store(args.grasps)
    arrays = evaluate_grasp_energies(
        grasps, args.objects, device=resolve_device(args.device), batch_size=args.batch_size, config=energy_config, contact_samples=args.contact_samples
    )
    arrays["passes_energy_thresholds"] = thresholds.passes(arrays) & (arrays["energy_failure_reason"] == "")
    grasps.arrays.update(arrays)
    attrs = {
        "energy": {
            "source": str(args.grasps),
            "config": dataclasses.asdict(energy_config),
            "thresholds": dataclasses.asdict(thresholds),
            "contact_samples": args.contact_samples,
        }
    }
    write_grasp_store(args.out, grasps, attrs)
    for line in summary_lines(arrays):
        print(line)
    print(f"wrote {args.out}")
    return 0
