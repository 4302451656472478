"""Post-optimization throughput (200 annealed iterations on E_post) and CVAE sampling throughput.

    python benchmarks/timing/bench_post_optimize.py [--threads 2] [--batches 256 1024] [--objects DIR ...]

Objects: ``--objects`` prepared-object dirs (every asset in them is used), or by default
four primitives prepared at the default SDF resolution in a temporary folder. Poses:
grasp-like poses with the hand at the object (``tests/demo_grasps.py``), as CVAE samples
are, so the timing is the one of hands in contact, not of hands far away. Sampling uses
a freshly initialized model of the reference sizes (its speed does not depend on the
weights) at 512 points per cloud. Prints one table row per measurement.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

# The grasp-like poses of the model and post-optimization tests (tests/demo_grasps.py), shared rather than copied.
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))


def prepare_primitives(root: str) -> list[str]:
    import trimesh

    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    meshes = {
        "sphere": trimesh.creation.icosphere(subdivisions=3, radius=1 / 1.03),
        "box": trimesh.creation.box(extents=[1.2, 0.9, 0.7]),
        "cylinder": trimesh.creation.cylinder(radius=0.55, height=1.3),
        "capsule": trimesh.creation.capsule(height=0.9, radius=0.45),
    }
    for object_id, mesh in meshes.items():
        write_asset(mesh, object_id, root, AssetBuildSettings(), {"source": "benchmark"}, convex_pieces=[mesh])
    return list(meshes)


def measure(assets, batches, iterations: int, sample_grasps: int) -> list[dict]:
    """Rows (benchmark, size, value, unit, note): post-optimization per batch size, then CVAE sampling."""
    from demo_grasps import facing_grasps

    from dexlite_pipeline.energy.config import EnergyConfig
    from dexlite_pipeline.energy.grasp_energy import GraspEnergy
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.config import ModelConfig
    from dexlite_pipeline.model.network import GraspCVAE
    from dexlite_pipeline.optim.config import PostOptimizeConfig
    from dexlite_pipeline.optim.post import refine
    from dexlite_pipeline.optim.config import AnnealingSchedule
    from dexlite_pipeline.model.sampling import synthesize

    ids = [a.object_id for a in assets]
    hand = ShadowHand()
    config = PostOptimizeConfig(annealing=AnnealingSchedule(iterations=iterations))
    energy = GraspEnergy.from_assets(hand, assets, EnergyConfig(weights=config.energy_weights, object_point_spacing_m=config.energy_point_spacing_m))
    rows = []
    for batch in batches:
        grasps = facing_grasps(hand, ids, batch, seed=batch)
        started, cpu_started = time.perf_counter(), time.process_time()
        result = refine(
            energy, torch.as_tensor(grasps.hand_pose), energy.object_index(grasps.object_id), torch.as_tensor(grasps.scale),
            PostOptimizeConfig(annealing=AnnealingSchedule(iterations=iterations), batch_size=batch), torch.Generator().manual_seed(0),
        )
        seconds, cpu_seconds = time.perf_counter() - started, time.process_time() - cpu_started
        before, after = np.median(result.arrays["raw_E_post"]), np.median(result.arrays["E_post"])
        rows.append({
            "benchmark": "post-optimization", "size": f"batch {batch} x {iterations} it", "value": batch / seconds, "unit": "grasps/s",
            "note": f"{seconds:.1f} s wall, {cpu_seconds:.1f} s CPU; median E_post {before:.3g} -> {after:.3g}",
        })
    model = GraspCVAE(ModelConfig()).eval()
    clouds = ObjectClouds(assets)
    object_index = np.arange(sample_grasps) % len(ids)
    scale = np.full(sample_grasps, 0.08, np.float32)
    synthesize(model, clouds, object_index[:8], scale[:8], 512, torch.Generator().manual_seed(0))  # warm-up
    started = time.perf_counter()
    synthesize(model, clouds, object_index, scale, 512, torch.Generator().manual_seed(1))
    seconds = time.perf_counter() - started
    rows.append({
        "benchmark": "CVAE sampling", "size": f"{sample_grasps} grasps, {len(ids)} objects, 512 points", "value": sample_grasps / seconds,
        "unit": "grasps/s", "note": "PointNet once per object + decoder (reference sizes)",
    })
    return rows


def run(quick: bool = False) -> list[dict]:
    """Entry point for ``benchmarks/timing/run_all.py``: small sizes when ``quick``."""
    from dexlite_pipeline.objects.assets import load_asset

    with tempfile.TemporaryDirectory() as tmp:
        assets = [load_asset(tmp, oid) for oid in prepare_primitives(tmp)]
    return measure(assets, [16] if quick else [256, 1024], 10 if quick else 200, 256 if quick else 4096)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--batches", type=int, nargs="+", default=[256, 1024])
    parser.add_argument("--iterations", type=int, default=200)
    parser.add_argument("--objects", action="append", default=[], help="prepared objects dir (default: four primitives)")
    parser.add_argument("--sample-grasps", type=int, default=4096, help="grasps decoded in the sampling measurement")
    args = parser.parse_args()

    from dexlite_pipeline.device import set_threads
    from dexlite_pipeline.objects.assets import available_object_ids, load_asset

    set_threads(args.threads)
    with tempfile.TemporaryDirectory() as tmp:
        dirs = args.objects or [tmp]
        ids = sorted(available_object_ids(dirs)) if args.objects else prepare_primitives(tmp)
        assets = [load_asset(dirs, oid) for oid in ids]
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, {len(ids)} objects")
    for row in measure(assets, args.batches, args.iterations, args.sample_grasps):
        print(f"{row['benchmark']:<20}{row['size']:<40}{row['value']:>10.1f} {row['unit']:<10}{row['note']}")


if __name__ == "__main__":
    main()
