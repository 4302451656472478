"""How deep a run's grasps start, by the lift test's measure and by dense exact distances to the mesh.

    python benchmarks/experiments/penetration_agreement.py RESULTS_DIR [--held-only] [--max-grasps 400] [--recompute] [--out agreement.csv]

Reads every grasp store under ``RESULTS_DIR/eval/sim/`` (the evaluation's simulated grasps, with
``initial_penetration_mm``, the lift test's start depth) and computes for each grasp (the held ones
with ``--held-only``; at most ``--max-grasps``, a seeded choice):

- ``exact_mm``: the two-sided reference, the deeper of 2,000 surface points per hand shape inside the
  mesh (exact point-to-mesh distance) and 200,000 mesh surface points inside the hand's capsules and
  boxes (their analytic distances);
- ``hand_points_mm``: the hand's own 1,210 surface points against the mesh alone (one direction, the
  coarse "exact" measure the project used to quote).

With ``--recompute`` the lift test's depth is measured again by this checkout's code (the judged
depth, ``GraspEnergy.judged_depth_m``) instead of read from the stores.

Prints per method the p50 / p90 / max of |lift test − exact| and the share of grasps whose start
depth is at most 1, 2, 3, 5 and 10 mm by each measure; writes the per-grasp table with ``--out``.
Objects are read from ``RESULTS_DIR/objects`` and the folders beside the stores. About 0.3 s per grasp.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def reference_depths(hand, dense_hand, mesh, poses: np.ndarray, scale: float, samples: int = 200_000) -> tuple[np.ndarray, np.ndarray]:
    """(two-sided dense exact depth, hand points against the mesh) in mm for poses (B, 28) on ``mesh`` (normalized) at ``scale``."""
    import torch
    import trimesh

    from dexlite_pipeline.objects.mesh_distance import MeshDistance

    scaled = mesh.copy()
    scaled.apply_scale(scale)
    distance = MeshDistance.from_mesh(scaled.vertices, scaled.faces)
    points, _ = trimesh.sample.sample_surface(scaled, samples, seed=1)
    object_points = torch.as_tensor(points, dtype=torch.float32)[None]
    exact, coarse = [], []
    for pose in poses:
        p = torch.as_tensor(pose, dtype=torch.float32)[None]
        dense_surface = dense_hand.surface_points(dense_hand.forward(p))[0].numpy()
        hand_in_object = distance.query(dense_surface)[0].max()
        object_in_hand = float(dense_hand.collision_signed_distance(dense_hand.forward(p), object_points).max())
        exact.append(max(hand_in_object, object_in_hand, 0.0))
        coarse.append(max(distance.query(hand.surface_points(hand.forward(p))[0].numpy())[0].max(), 0.0))
    return 1000.0 * np.asarray(exact), 1000.0 * np.asarray(coarse)


def judged_depth_m(hand, asset, poses: np.ndarray, scale: float) -> np.ndarray:
    """(B,) the judged start depth (m) of poses on one object at one scale, by this checkout's code."""
    import torch

    from dexlite_pipeline.energy.grasp_energy import GraspEnergy

    energy = GraspEnergy.from_assets(hand, [asset], max_scale=scale)
    pose = torch.as_tensor(poses, dtype=torch.float32)
    return energy.judged_depth_m(hand.forward(pose), torch.zeros(len(pose), dtype=torch.long), torch.full((len(pose),), scale)).numpy()


def main() -> None:
    import pandas as pd

    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.io.grasp_store import read_grasp_store
    from dexlite_pipeline.objects.assets import find_asset_dir, load_asset

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path)
    parser.add_argument("--held-only", action="store_true")
    parser.add_argument("--max-grasps", type=int, default=400)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--recompute", action="store_true", help="measure the start depth with this checkout's code")
    args = parser.parse_args()
    sim = args.results / "eval" / "sim"
    stores = sorted(sim.glob("shard_*.zarr"))
    if not stores:
        raise SystemExit(f"{sim}: no evaluation shards (run the pipeline first)")
    rows = []
    for path in stores:
        grasps = read_grasp_store(path)
        depth = np.asarray(grasps.arrays["initial_penetration_mm"], np.float64)
        keep = np.isfinite(depth) & (np.asarray(grasps.arrays["lift_success"], bool) if args.held_only else True)
        for i in np.flatnonzero(keep):
            rows.append((str(grasps.object_id[i]), float(grasps.scale[i]), grasps.hand_pose[i].astype(np.float64), depth[i],
                         str(grasps.arrays["method"][i]), bool(grasps.arrays["lift_success"][i])))  # fmt: skip
    rng = np.random.default_rng(0)
    if len(rows) > args.max_grasps:
        rows = [rows[i] for i in sorted(rng.choice(len(rows), args.max_grasps, replace=False))]
    hand, dense_hand = ShadowHand(), ShadowHand(surface_points_per_shape=2000)
    dirs = [args.results / "objects", sim]
    table = []
    for (object_id, scale), group in pd.DataFrame(rows, columns=["object_id", "scale", "pose", "lift_mm", "method", "held"]).groupby(["object_id", "scale"]):
        import trimesh

        mesh = trimesh.load(find_asset_dir(dirs, object_id) / "mesh.obj", force="mesh", process=False)
        poses = np.stack(group["pose"].to_list())
        exact, coarse = reference_depths(hand, dense_hand, mesh, poses, scale)
        part = group.drop(columns="pose").assign(exact_mm=exact, hand_points_mm=coarse)
        if args.recompute:
            part["lift_mm"] = 1000.0 * judged_depth_m(hand, load_asset(dirs, object_id), poses, scale)
        table.append(part)
    table = pd.concat(table).sort_values(["method", "object_id"])
    table["error_mm"] = (table["lift_mm"] - table["exact_mm"]).abs()
    print(f"{len(table)} grasps ({'held only' if args.held_only else 'all simulated'}) from {args.results}")
    for method, part in [("all", table), *table.groupby("method")]:
        error = part["error_mm"]
        caps = "  ".join(
            f"≤{c} mm {100 * np.mean(part['lift_mm'] <= c):.0f}/{100 * np.mean(part['exact_mm'] <= c):.0f}/{100 * np.mean(part['hand_points_mm'] <= c):.0f}%"
            for c in (1, 2, 3, 5, 10)
        )
        print(f"{method:<24} n {len(part):>4}  |lift − exact| p50 {error.median():.2f} p90 {np.percentile(error, 90):.2f} max {error.max():.2f} mm;"
              f"  start depth (lift / exact / hand points): {caps}")  # fmt: skip
    if args.out:
        table.to_csv(args.out, index=False)


if __name__ == "__main__":
    main()
