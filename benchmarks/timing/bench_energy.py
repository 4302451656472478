"""Energy and optimization benchmark: cost of an energy step and of optimization from scratch.

    python benchmarks/timing/bench_energy.py                 # full: batches 64/256/1024, optimization from scratch on 4 objects
    python benchmarks/timing/bench_energy.py --quick         # small sizes, to check it runs
    python benchmarks/timing/bench_energy.py --objects results/objects   # prepared objects instead of built ones

1. Time of one energy-and-gradient step (forward kinematics, all five terms, backward) for
   batches of 64, 256 and 1024 grasps with the hands AT the object: poses come from a short
   optimization (so fingers touch the surface), tiled to the batch size. Measured with
   1 and with 2 torch threads (the machine has 2 cores); each row gives the median wall
   time, and in its note the minimum, the CPU time and the load average (the cores are
   shared). With 2 threads while other jobs run, OpenMP's default spin-waiting makes a
   step 5-20x slower than with 1 thread (measured: 320-480 ms at batch 256, load ~5);
   ``OMP_WAIT_POLICY=PASSIVE`` in the environment removes that (50 ms, as 1 thread), so
   the note records the policy. Reported with the median contact distance and the share
   of grasps that penetrate, to show where the hands are. Target: <= 40 ms at 256.
2. Optimization from scratch with the schedule of ``config.yaml`` (section ``optimize_grasps``): pass
   fraction of the energy thresholds and threshold-passing grasps per hour. On a shared
   machine wall time depends on the other jobs, so the rate is given both per wall second
   and per CPU second of this process (one thread: the rate one dedicated core gives).

Objects: the default pipeline's kind (pybullet_data random meshes, normalized like
DexGraspNet, SDF grid at the config's resolution), built into a temporary folder.
``run(quick)`` returns the rows for ``benchmarks/timing/run_all.py``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[2]


def build_objects(directory: Path, count: int, seed: int, resolution: int) -> list[str]:
    """Prepare ``count`` embedded pybullet_data meshes (skipping ones that fail the mesh checks)."""
    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings
    from dexlite_pipeline.objects.asset_building import load_source_mesh, normalize_mesh, prepared_solid
    from dexlite_pipeline.objects.sources import builtin_sources

    settings = AssetBuildSettings(sdf_resolution=resolution)
    ids = []
    for source in builtin_sources(count * 3, seed):
        try:
            mesh = prepared_solid(load_source_mesh(source))[0]
        except Exception:  # a mesh the pipeline would reject; take the next one
            continue
        mesh, _, _ = normalize_mesh(mesh)
        write_asset(mesh, source.object_id, directory, settings, {"source": source.source}, convex_pieces=[mesh.convex_hull])
        ids.append(source.object_id)
        if len(ids) == count:
            break
    return ids


def _optimize_config(quick: bool):
    from dexlite_pipeline.config import from_section, load_config
    from dexlite_pipeline.energy.config import EnergyConfig
    from dexlite_pipeline.optim.config import OptimizeGraspsConfig

    config = load_config(ROOT / "config.yaml")
    section = from_section(OptimizeGraspsConfig, config.get("optimize_grasps"), "config.optimize_grasps")
    energy = from_section(EnergyConfig, config.get("energy"), "config.energy")
    if quick:
        section = dataclasses.replace(section, grasps_per_object=2, annealing=dataclasses.replace(section.annealing, iterations=100))
    return section, energy, int(config["objects"].get("sdf_resolution", 96))


def poses_at_object(energy, hulls, optimize_config, count: int, generator):
    """Poses touching the objects: a short, fast-cooling optimization from close starts."""
    from dexlite_pipeline.optim.annealing import optimize
    from dexlite_pipeline.optim.config import AnnealingConfig, InitConfig
    from dexlite_pipeline.optim.init import initial_poses

    object_index = torch.arange(count) % len(energy.object_ids)
    scale = torch.tensor(optimize_config.scales, dtype=torch.float32)[torch.arange(count) % len(optimize_config.scales)]
    init = initial_poses(energy.hand, hulls, object_index, scale, InitConfig(distance_m=(0.06, 0.09)), generator)
    schedule = AnnealingConfig(iterations=300, step_size_period=6, temperature_period=4, final_contact_samples=256)
    result = optimize(energy, init, object_index, scale, schedule, generator)
    return result.hand_pose, result.contact_index, object_index, scale


def time_energy_steps(energy, pose, contacts, object_index, scale, batches, repeats: int, thread_counts=(1, 2)) -> list[dict]:
    """Wall time of one energy-and-gradient step per batch size and torch thread count.

    The value is the median wall time over ``repeats`` steps; the note gives the minimum
    (the cost with the least interference from other jobs), the median CPU time of this
    process (all its threads) and the load average while measuring, since the machine's
    cores are shared.
    """
    rows = []
    previous_threads = torch.get_num_threads()
    for threads in thread_counts:
        torch.set_num_threads(threads)
        for batch in batches:
            tile = -(-batch // len(pose))
            x = pose.repeat(tile, 1)[:batch].clone().requires_grad_(True)
            c, o, s = contacts.repeat(tile, 1)[:batch], object_index.repeat(tile)[:batch], scale.repeat(tile)[:batch]

            def step():
                result = energy(x, object_index=o, scale=s, contact_index=c)
                torch.autograd.grad(result.total.sum(), x)
                return result

            result = step()
            wall, cpu = [], []
            load_before = os.getloadavg()[0]
            for _ in range(repeats):
                t_wall, t_cpu = time.perf_counter(), time.process_time()
                step()
                wall.append(time.perf_counter() - t_wall)
                cpu.append(time.process_time() - t_cpu)
            load = max(load_before, os.getloadavg()[0])
            rows.append({
                "benchmark": f"energy+gradient step, {threads} thread{'s' if threads > 1 else ''}",
                "size": f"batch {batch}",
                "value": 1000 * float(np.median(wall)),
                "unit": "ms (wall, median)",
                "note": f"min {1000 * min(wall):.1f} ms; cpu {1000 * float(np.median(cpu)):.1f} ms (median, all threads); "
                f"{repeats} steps; load avg {load:.1f} on {os.cpu_count()} cores; OMP_WAIT_POLICY {os.environ.get('OMP_WAIT_POLICY', 'unset')}; "
                f"hands at the object: median contact distance "
                f"{float(result.contact_distance_mm.median()):.1f} mm, {100 * float((result.penetration_mm > 0).float().mean()):.0f}% penetrate",
            })
    torch.set_num_threads(previous_threads)
    return rows


def optimization_throughput(assets, optimize_config, energy_config, generator) -> list[dict]:
    from dexlite_pipeline.optim.from_scratch import synthesize

    t_cpu = time.process_time()
    grasps, stats = synthesize(assets, optimize_config, energy_config, generator)
    cpu = time.process_time() - t_cpu
    passing = stats["passing"]
    terms = {k: float(np.mean(grasps.arrays[k] < t)) for k, t in (("E_fc", 0.3), ("E_dis", 0.005), ("E_pen", 0.001))}
    schedule = optimize_config.annealing
    note = (f"{stats['grasps']} grasps, {schedule.iterations} it, init {optimize_config.init.distance_m} m; pass {100 * stats['pass_fraction']:.1f}% "
            f"(E_fc {100 * terms['E_fc']:.0f}%, E_dis {100 * terms['E_dis']:.0f}%, E_pen {100 * terms['E_pen']:.0f}%); "
            f"{1000 * cpu / max(stats['grasps'] * schedule.iterations, 1):.3f} ms cpu per grasp-iteration")
    return [
        {"benchmark": "optimization from scratch pass fraction", "size": f"{len(assets)} objects", "value": 100 * stats["pass_fraction"], "unit": "%", "note": note},
        {"benchmark": "optimization from scratch passing grasps/hour", "size": "per wall hour", "value": passing / stats["seconds"] * 3600, "unit": "grasps/h",
         "note": f"wall {stats['seconds']:.0f} s (shared machine)"},
        {"benchmark": "optimization from scratch passing grasps/hour", "size": "per CPU hour (1 thread)", "value": passing / cpu * 3600, "unit": "grasps/h",
         "note": f"cpu {cpu:.0f} s"},
    ]


def run(quick: bool = False, objects_dir: str | None = None, object_count: int = 4) -> list[dict]:
    from dexlite_pipeline.energy.grasp_energy import GraspEnergy
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.objects.assets import available_object_ids, load_asset
    from dexlite_pipeline.optim.init import HullSampler

    torch.set_num_threads(1)
    optimize_config, energy_config, resolution = _optimize_config(quick)
    with tempfile.TemporaryDirectory() as tmp:
        if objects_dir:
            ids = sorted(available_object_ids(objects_dir))[:object_count]
            directory = objects_dir
        else:
            directory = Path(tmp)
            ids = build_objects(directory, 2 if quick else object_count, seed=0, resolution=resolution)
        assets = [load_asset(directory, i) for i in ids]
        hand = ShadowHand()
        energy = GraspEnergy.from_assets(hand, assets, energy_config)
        generator = torch.Generator().manual_seed(0)
        pose, contacts, object_index, scale = poses_at_object(energy, HullSampler(assets), optimize_config, 16 if quick else 64, generator)
        rows = time_energy_steps(energy, pose, contacts, object_index, scale, (64, 256) if quick else (64, 256, 1024), 2 if quick else 10)
        rows += optimization_throughput(assets, optimize_config, energy_config, torch.Generator().manual_seed(1))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--objects", default=None, help="prepared objects dir to use instead of building some")
    parser.add_argument("--object-count", type=int, default=4)
    args = parser.parse_args()
    for row in run(args.quick, args.objects, args.object_count):
        print(f"{row['benchmark']:<42} {row['size']:<26} {row['value']:>10.1f} {row['unit']:<18} {row['note']}")


if __name__ == "__main__":
    main()
