"""MuJoCo lift-test throughput on real grasps: grasps/s on N worker threads.

    DEXLITE_DEXGRASPNET_ROOT=DIR python benchmarks/timing/bench_lift.py   # real DexGraspNet grasps in DIR, 2 workers
    python benchmarks/timing/bench_lift.py --count 128 --six-directions
    python benchmarks/timing/bench_lift.py --grasps G.zarr --objects DIR   # any grasp store
    python benchmarks/timing/bench_lift.py --single-contact         # lift.multi_contact off (~15% faster)
    python benchmarks/timing/bench_lift.py --quick                  # 32 grasps: checks that it runs

Real grasps matter here: a held object costs the full 1,350 steps with contacts, a
dropped one is cheap (no contacts, and the rest of its fall is extrapolated), so
synthetic poses that mostly miss would flatter the rate. The DexGraspNet sample is
imported with the project's importer into a temporary folder (SDF grid 64^3).

Reported per worker count (N worker threads of this process, as in ``run_lift_tests``):
wall-clock grasps/s, the CPU seconds per grasp summed over the threads, and from that
the rate 2 dedicated cores would give (2 / CPU s per grasp). On a shared machine the wall
rate follows the other jobs' load, so the load average is printed beside it. Target:
>= 20 grasps/s on 2 cores. ``run(quick)`` returns rows for run_all.py.
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

# a DexGraspNet download (dataset/, meshdata/) to read real grasps from; none by default
SAMPLE = Path(os.environ.get("DEXLITE_DEXGRASPNET_ROOT", "/nonexistent-dexgraspnet-root"))


def _own_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def sample_grasps(workdir: Path):
    """The DexGraspNet sample's grasps and the folder its objects were prepared into."""
    from dexlite_pipeline.io.config import DexGraspNetConfig
    from dexlite_pipeline.io.dexgraspnet import import_dexgraspnet
    from dexlite_pipeline.objects.config import AssetBuildSettings

    objects = workdir / "objects"
    result = import_dexgraspnet(SAMPLE, objects, AssetBuildSettings(sdf_resolution=64), DexGraspNetConfig(), seed=0)
    return result.grasps, objects


def measure(grasps, objects_dir, config, workers: int) -> dict:
    """One timed run: wall and CPU seconds (all threads of this process)."""
    from dexlite_pipeline.sim.lift import run_lift_tests

    load_before = os.getloadavg()[0]
    cpu0, start = _own_cpu_s(), time.perf_counter()
    result = run_lift_tests(grasps, [objects_dir], config, workers)
    wall = time.perf_counter() - start
    cpu = _own_cpu_s() - cpu0
    n = len(grasps)
    rate = float(np.mean(result["lift_success"]))
    note = f"success {100 * rate:.1f}%, friction {config.friction}, multi_contact {config.multi_contact}; load avg {load_before:.1f} -> {os.getloadavg()[0]:.1f}"
    if config.six_directions:
        note += f"; six-direction pass {100 * float(np.mean(result['six_dir_success'])):.1f}%"
    return {"n": n, "wall_s": wall, "cpu_s": cpu, "note": note}


def rows_for(label: str, workers: int, m: dict) -> list[dict]:
    per_grasp_cpu = m["cpu_s"] / m["n"]
    size = f"{m['n']} grasps, {workers} worker{'s' if workers > 1 else ''}"
    return [
        {"benchmark": f"{label} wall rate", "size": size, "value": m["n"] / m["wall_s"], "unit": "grasps/s", "note": m["note"]},
        {"benchmark": f"{label} CPU per grasp", "size": size, "value": per_grasp_cpu, "unit": "CPU s", "note": "incl. scene compilation and squeeze targets"},
        {"benchmark": f"{label} on 2 dedicated cores", "size": size, "value": 2.0 / per_grasp_cpu, "unit": "grasps/s", "note": "2 / CPU s per grasp"},
    ]


def run(quick: bool = False, count: int | None = None, workers: int = 2, six_directions: bool = False,
        grasps_path: str | None = None, objects: str | None = None, friction: float | None = None,
        single_contact: bool = False) -> list[dict]:
    from dexlite_pipeline.io.grasp_store import read_grasp_store
    from dexlite_pipeline.sim.config import LiftConfig

    count = count or (32 if quick else None)
    with tempfile.TemporaryDirectory(prefix="dexlite-bench-lift-") as tmp:
        if grasps_path:
            grasps, objects_dir = read_grasp_store(grasps_path), Path(objects)
        elif (SAMPLE / "dataset").is_dir():
            grasps, objects_dir = sample_grasps(Path(tmp))
        else:
            return [{"benchmark": "lift test", "size": "-", "value": float("nan"), "unit": "grasps/s",
                     "note": f"no real grasps: {SAMPLE} absent and no --grasps given"}]
        if count and count < len(grasps):
            grasps = grasps.select(np.sort(np.random.default_rng(0).choice(len(grasps), count, replace=False)))
        overrides = {"friction": friction} if friction is not None else {}
        config = LiftConfig(multi_contact=not single_contact, **overrides)
        rows = []
        for n_workers in sorted({1, workers}):
            rows += rows_for("lift test", n_workers, measure(grasps, objects_dir, config, n_workers))
        if six_directions:
            six = grasps.select(np.arange(min(len(grasps), 32 if quick else 96)))
            six_config = LiftConfig(six_directions=True, multi_contact=not single_contact, **overrides)
            rows += rows_for("lift + six-direction test", workers, measure(six, objects_dir, six_config, workers))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--count", type=int, default=None, help="grasps to simulate (seeded subset; default all)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--six-directions", action="store_true", help="also time the six-direction test (on up to 96 grasps)")
    parser.add_argument("--grasps", default=None, help="a grasp store instead of the DexGraspNet sample")
    parser.add_argument("--objects", default=None, help="objects dir of --grasps")
    parser.add_argument("--friction", type=float, default=None)
    parser.add_argument("--single-contact", action="store_true", help="lift.multi_contact off (one contact per touching pair)")
    args = parser.parse_args()
    if bool(args.grasps) != bool(args.objects):
        parser.error("--grasps and --objects go together")
    rows = run(args.quick, args.count, args.workers, args.six_directions, args.grasps, args.objects, args.friction, args.single_contact)
    width = max(len(r["benchmark"]) for r in rows)
    for r in rows:
        print(f"{r['benchmark']:<{width}}  {r['size']:<22}  {r['value']:9.3f} {r['unit']:<9}  {r['note']}")


if __name__ == "__main__":
    main()
