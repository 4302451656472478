"""CPU time of the surface-sample loss terms (``model.surface_terms``) per training step, with and without the training
grasps' nearest samples kept (``training_grasps``).

Synthetic and self-contained: Shadow Hand poses around spheres of 4 cm radius sampled with ``--samples`` surface points
each (the training clouds' default 4,096), batches of ``--batch`` grasps (training's 64) cycling over ``--grasps``
training grasps. The first pass over the grasps (which fills the kept indices) is not timed; then ``--steps`` steps
(value and backward pass) are, on one torch thread.

    python benchmarks/timing/bench_surface_terms.py [--grasps 640] [--batch 64] [--samples 4096] [--steps 30]

Prints one Markdown row per term and mode: CPU-s per step. Only ``surface_dis`` keeps anything: ``surface_pen`` searches
the samples nearest the decoded hand, which every step moves.
"""

from __future__ import annotations

import argparse
import time

import torch


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grasps", type=int, default=640)
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--samples", type=int, default=4096)
    parser.add_argument("--steps", type=int, default=30)
    args = parser.parse_args()
    torch.set_num_threads(1)

    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix
    from dexlite_pipeline.model.config import SURFACE_DISTANCE_TERM, SURFACE_PENETRATION_TERM
    from dexlite_pipeline.model.surface_terms import surface_terms

    hand = ShadowHand()
    generator = torch.Generator().manual_seed(0)
    directions = torch.randn(4, args.samples, 3, generator=generator)
    directions = directions / directions.norm(dim=-1, keepdim=True)
    clouds = argparse.Namespace(surface=directions * 0.04, normals=directions)  # what the terms read of ObjectClouds
    palm_rot = euler_xyz_to_matrix(torch.randn(args.grasps, 3, generator=generator))
    palm_t = torch.randn(args.grasps, 3, generator=generator) * 0.02
    joints = torch.zeros(args.grasps, 22)
    object_index = torch.randint(0, 4, (args.grasps,), generator=generator)
    scale = torch.ones(args.grasps)

    print("| term | nearest samples of the training grasps | CPU-s per step |")
    print("| --- | --- | ---: |")
    for name in (SURFACE_DISTANCE_TERM, SURFACE_PENETRATION_TERM):
        for kept in ((False, True) if name == SURFACE_DISTANCE_TERM else (False,)):  # surface_pen searches at the decoded pose
            terms = surface_terms(hand, clouds, (name,), training_grasps=args.grasps if kept else 0)

            def step(k: int) -> None:
                rows = torch.arange(k * args.batch, (k + 1) * args.batch) % args.grasps
                rot = palm_rot[rows].clone().requires_grad_(True)
                translation = palm_t[rows].clone().requires_grad_(True)
                target = (palm_rot[rows], palm_t[rows] + 0.003, joints[rows])  # decoded 3 mm off the training grasp
                extra = {"grasp_index": rows} if kept else {}
                terms(rot, translation, joints[rows], object_index[rows], scale[rows], target, **extra)[name].mean().backward()

            for k in range(-(-args.grasps // args.batch)):
                step(k)
            start = time.process_time()
            for k in range(args.steps):
                step(k)
            print(f"| {name} | {'kept' if kept else 'searched each step'} | {(time.process_time() - start) / args.steps:.4f} |")


if __name__ == "__main__":
    main()
