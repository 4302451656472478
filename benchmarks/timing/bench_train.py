"""CVAE training speed: optimizer steps per second at the default configuration.

    python benchmarks/timing/bench_train.py [--threads 2] [--steps 300] [--grasps 256] [--objects 8]

Trains the default model (config.yaml's ``train`` section: sizes, batch, clouds per batch,
points per cloud, energy weights) on grasp-like poses (``tests/demo_grasps.py``) over
``--objects`` primitives at three scales, so the batches hold as many clouds as a real run's.
Steps per second do not depend on what the grasps are, only on the batch composition and
the network sizes. Prints one table row: steps/s and the seconds the default budget
(``train.max_steps``) takes at that speed.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch
import yaml

# The grasp-like poses of the model and post-optimization tests (tests/demo_grasps.py), shared rather than copied.
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--steps", type=int, default=300, help="steps timed (after 20 warm-up steps)")
    parser.add_argument("--grasps", type=int, default=256)
    parser.add_argument("--objects", type=int, default=8)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)

    import trimesh
    from demo_grasps import facing_grasps

    from dexlite_pipeline.config import from_section
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.model.data import build_training_data
    from dexlite_pipeline.model.config import TrainConfig
    from dexlite_pipeline.model.training import train_cvae
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    config_path = Path(__file__).resolve().parents[2] / "config.yaml"
    section = yaml.safe_load(config_path.read_text())["train"]
    default = from_section(TrainConfig, section, "config.train")
    with tempfile.TemporaryDirectory() as root:
        ids = [f"box{i}" for i in range(args.objects)]
        rng = np.random.default_rng(0)
        for object_id in ids:
            mesh = trimesh.creation.box(extents=rng.uniform(0.6, 1.3, 3))
            write_asset(mesh, object_id, root, AssetBuildSettings(sdf_resolution=32), {"source": "benchmark"}, convex_pieces=[mesh])
        assets = [load_asset(root, o) for o in ids]
        hand = ShadowHand()
        grasps = facing_grasps(hand, ids, args.grasps, seed=0, scales=(0.08, 0.1, 0.12))
        data = build_training_data(grasps, assets, hand)
        rows = np.arange(len(grasps))
        if any(default.weights()[k] > 0 for k in ("fc", "dis", "pen", "spen", "joints")):
            raise SystemExit("bench_train.py times the default (energy weights 0); energy terms need an energy model")
        timings = []
        for steps in (20, 20 + args.steps):
            config = TrainConfig(**{**default.__dict__, "max_steps": steps, "validation_fraction": 0.0})
            started = time.perf_counter()
            train_cvae(data, rows, np.zeros(0, np.int64), config, None, seed=0)
            timings.append(time.perf_counter() - started)
    rate = args.steps / (timings[1] - timings[0])
    print("| benchmark | value | note |")
    print("| --- | --- | --- |")
    print(
        f"| CVAE training, default config ({default.batch_size} grasps, {default.clouds_per_batch} clouds x "
        f"{default.points_per_cloud} points a step), {args.threads} threads | {rate:.1f} steps/s | "
        f"default budget {default.max_steps} steps = {default.max_steps / rate:.0f} s |"
    )


if __name__ == "__main__":
    main()
