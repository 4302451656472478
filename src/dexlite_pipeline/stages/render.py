"""``dexlite render GRASPS.zarr --objects DIR --index K --out FILE.png``: picture of one grasp."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grasps", help="grasp store (.zarr)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir (repeatable)")
    parser.add_argument("--index", type=int, default=0, help="row of the grasp to render (0-based)")
    parser.add_argument("--out", required=True, help="output PNG file")
    parser.add_argument("--size-px", type=int, default=400, help="height of each view in pixels")


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.io.grasp_store import read_grasp_store
    from dexlite_pipeline.report.render import RenderError, render_grasp_png

    grasps = read_grasp_store(args.grasps)
    if not 0 <= args.index < len(grasps):
        raise RenderError(f"{args.grasps}: index {args.index} out of range (store has {len(grasps)} grasps)")
    k = args.index
    object_id, scale = str(grasps.object_id[k]), float(grasps.scale[k])
    bad = [i for i, v in enumerate(np.asarray(grasps.hand_pose[k], dtype=np.float64)) if not np.isfinite(v)]
    if bad:
        raise RenderError(f"{args.grasps}: row {k} ({object_id}): hand_pose is not finite at position(s) {', '.join(map(str, bad))}")
    if not np.isfinite(scale) or scale <= 0:
        raise RenderError(f"{args.grasps}: row {k} ({object_id}): scale {scale} is not a positive number")
    title = f"{object_id}  scale {scale:.3f}  grasp {k}"
    if "lift_success" in grasps.arrays:
        title += "  lift " + ("success" if bool(grasps.arrays["lift_success"][k]) else "failure")
    render_grasp_png(ShadowHand(), grasps.hand_pose[k], object_id, scale, args.objects, out=args.out, title=title, size_px=args.size_px)
    print(f"wrote {args.out}")
    return 0
