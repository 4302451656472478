"""Object preparation and stability-filter benchmark.

    python benchmarks/timing/bench_stability.py                  # full: the default 40 objects, config.yaml settings
    python benchmarks/timing/bench_stability.py --quick          # 6 objects, small grids: checks that it runs
    python benchmarks/timing/bench_stability.py --objects 20 --workers 2
    python benchmarks/timing/bench_stability.py --prepared results/objects   # stability only, on prepared objects

1. ``prepare_objects`` on the first N embedded objects of the default selection (seeded
   pybullet_data mix, the ``objects`` settings of config.yaml): wall time, wall and CPU
   seconds per object (CPU summed over the worker processes). Target: the default 40
   objects in under 5 minutes on 2 cores.
2. Where one object's preparation time goes (CPU seconds in this process, single
   threaded): load + repair + checks, CoACD, SDF grid, surface samples; median and max
   over the first ``--breakdown`` objects.
3. The stability filter on the prepared objects (``stability`` settings of config.yaml)
   with 1 and with ``--workers`` processes: objects per second. Target: >= 5 objects/s on
   2 cores. Each object is simulated ``--repeat`` times per measurement to get a stable rate.

On a shared machine the wall time depends on the other jobs; CPU seconds show what one
dedicated core costs. ``run(quick)`` returns rows (benchmark, size, value, unit, note) for
``benchmarks/timing/run_all.py``.
"""

from __future__ import annotations

import argparse
import dataclasses
import resource
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _config_sections(quick: bool):
    from dexlite_pipeline.config import from_section, load_config
    from dexlite_pipeline.objects.config import ObjectsConfig
    from dexlite_pipeline.objects.config import StabilityConfig

    config = load_config(ROOT / "config.yaml")
    objects = from_section(ObjectsConfig, config["objects"], "config.objects")
    if quick:
        objects = dataclasses.replace(objects, sdf_resolution=32, surface_points=512, coacd_mcts_iterations=20)
    stability = from_section(StabilityConfig, config.get("stability"), "config.stability")
    return int(config["seed"]), objects, stability


def bench_prepare(workdir: Path, count: int, workers: int, seed: int, objects) -> tuple[list[dict], object]:
    from dexlite_pipeline.objects.prepare import prepare_objects
    from dexlite_pipeline.objects.sources import builtin_sources

    sources = builtin_sources(objects.builtin_count, seed)[:count]
    cpu0, start = _children_cpu_s(), time.perf_counter()
    catalog = prepare_objects(sources, workdir, objects, seed, workers)
    wall = time.perf_counter() - start
    cpu = _children_cpu_s() - cpu0
    ok = int((catalog["status"] == "ok").sum())
    note = f"{ok} ok, {len(catalog) - ok} rejected; SDF {objects.sdf_resolution}^3, CoACD {objects.coacd_mcts_iterations} iterations"
    rows = [
        {"benchmark": "prepare_objects wall", "size": f"{len(sources)} objects, {workers} workers", "value": wall, "unit": "s", "note": note},
        {"benchmark": "prepare_objects per object", "size": f"{workers} workers", "value": wall / len(sources), "unit": "s wall", "note": ""},
        {"benchmark": "prepare_objects CPU per object", "size": "worker processes", "value": cpu / len(sources), "unit": "CPU s", "note": ""},
    ]
    return rows, catalog


def bench_breakdown(count: int, seed: int, objects) -> list[dict]:
    import numpy as np

    from dexlite_pipeline.objects.build import convex_decomposition, signed_distance_grid, surface_samples
    from dexlite_pipeline.objects.asset_building import MeshRejected, check_shape, load_source_mesh, normalize_mesh, prepared_solid
    from dexlite_pipeline.objects.sources import builtin_sources

    settings = objects.build_settings(seed)
    phases: dict[str, list[float]] = {"load, repair, check": [], "CoACD": [], "SDF grid": [], "surface samples": []}
    for source in builtin_sources(objects.builtin_count, seed)[:count]:
        t0 = time.process_time()
        try:
            raw = load_source_mesh(source)
            check_shape(raw)
            mesh = prepared_solid(raw)[0]
        except MeshRejected:
            continue
        mesh = normalize_mesh(mesh)[0]
        t1 = time.process_time()
        convex_decomposition(mesh, settings)
        t2 = time.process_time()
        signed_distance_grid(mesh, settings.sdf_resolution, settings.sdf_padding, settings.sdf_exact_band)
        t3 = time.process_time()
        surface_samples(mesh, settings.surface_points, settings.seed)
        t4 = time.process_time()
        for name, seconds in zip(phases, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
            phases[name].append(seconds)
    return [
        {"benchmark": f"prepare phase: {name}", "size": f"{len(values)} objects", "value": float(np.median(values)),
         "unit": "CPU s median", "note": f"max {max(values):.2f} s"}
        for name, values in phases.items()
        if values
    ]


def bench_stability(workdir: Path, catalog, workers: int, repeat: int, seed: int, stability) -> list[dict]:
    import pandas as pd

    from dexlite_pipeline.objects.stability import stability_table

    ok = catalog[catalog["status"] == "ok"]
    rows = []
    for n_workers in sorted({1, workers}):
        batch = pd.concat([ok] * repeat, ignore_index=True)  # duplicate rows: each is simulated again
        cpu0, start = _children_cpu_s(), time.perf_counter()
        table = stability_table(batch, [str(workdir)], stability, seed, n_workers)
        wall = time.perf_counter() - start
        cpu = _children_cpu_s() - cpu0
        stable = int(table["stable"].sum())
        rows.append(
            {
                "benchmark": "stability objects/s",
                "size": f"{len(batch)} objects, {n_workers} workers",
                "value": len(batch) / wall,
                "unit": "objects/s",
                "note": f"{cpu / len(batch) * 1000:.0f} CPU ms/object incl. worker start; {stable}/{len(batch)} stable",
            }
        )
    return rows


def run(
    quick: bool = False, count: int | None = None, workers: int = 2, repeat: int | None = None,
    prepared: str | None = None, breakdown: int | None = None,
) -> list[dict]:
    seed, objects, stability = _config_sections(quick)
    count = count or (6 if quick else objects.builtin_count)
    repeat = repeat or (1 if quick else 3)
    if prepared:
        from dexlite_pipeline.objects.assets import read_catalog

        return bench_stability(Path(prepared), read_catalog(prepared), workers, repeat, seed, stability)
    with tempfile.TemporaryDirectory(prefix="bench_stability_") as tmp:
        workdir = Path(tmp) / "objects"
        rows, catalog = bench_prepare(workdir, count, workers, seed, objects)
        rows += bench_breakdown(breakdown or (3 if quick else 8), seed, objects)
        rows += bench_stability(workdir, catalog, workers, repeat, seed, stability)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="few objects, small grids")
    parser.add_argument("--objects", type=int, default=None, help="objects to prepare (default: objects.builtin_count)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes")
    parser.add_argument("--repeat", type=int, default=None, help="simulations per object in the stability measurement")
    parser.add_argument("--prepared", default=None, help="objects dir already prepared: benchmark only the stability filter on it")
    parser.add_argument("--breakdown", type=int, default=None, help="objects timed phase by phase (default 8, quick 3)")
    args = parser.parse_args()
    rows = run(args.quick, args.objects, args.workers, args.repeat, args.prepared, args.breakdown)
    print(f"{'benchmark':<36} {'size':<28} {'value':>10}  unit        note")
    for row in rows:
        print(f"{row['benchmark']:<36} {row['size']:<28} {row['value']:>10.2f}  {row['unit']:<11} {row['note']}")


if __name__ == "__main__":
    main()
