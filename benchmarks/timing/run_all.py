"""All benchmarks of the pipeline in one table.

    python benchmarks/timing/run_all.py            # full sizes (tens of minutes on 2 busy CPU cores)
    python benchmarks/timing/run_all.py --quick    # small sizes, e.g. to check that everything runs
    python benchmarks/timing/run_all.py --only object_scaling lift --csv bench.csv

Each component measures itself in ``benchmarks/timing/bench_<name>.py``, which exposes
``run(quick: bool) -> list[dict]`` (keys benchmark, size, value, unit, note): hand FK +
energy step time against batch size and optimization from scratch grasps/s (``bench_energy``), hand
FK alone against pytorch-kinematics (``bench_kinematics``), the
MuJoCo lift test on real DexGraspNet grasps (``bench_lift``), post-optimization and CVAE
sampling grasps/s (``bench_post_optimize``), object preparation and the stability test
(``bench_stability``). This script runs every such module it finds, and adds what no
single component owns: how wall time grows with the number of objects (8, 16, 32), for
energy evaluation and for the lift test of a fixed number of grasps per object, on
synthetic primitives (boxes, spheres, cylinders, capsules) with synthetic approach poses
(palms 4-6 cm off the surface; cost only, not success). A module that is missing or fails
gives a row saying so; the others still run. Importable: ``run_benchmarks(quick=True)``.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import platform
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

BENCH_DIR = Path(__file__).resolve().parent


@dataclass
class Row:
    benchmark: str
    size: str
    value: float
    unit: str
    note: str = ""


@dataclass
class Context:
    """Shared, lazily built fixtures: a folder of synthetic objects."""

    workdir: Path
    quick: bool
    _objects: dict = None

    def objects(self, count: int) -> list[str]:
        """Ids of ``count`` synthetic objects prepared under ``workdir/objects`` (built once each)."""
        import trimesh

        from dexlite_pipeline.objects.build import write_asset
        from dexlite_pipeline.objects.config import AssetBuildSettings

        self._objects = self._objects or {}
        settings = AssetBuildSettings(sdf_resolution=32 if self.quick else 64, surface_points=512 if self.quick else 2048)
        rng = np.random.default_rng(0)
        for k in range(len(self._objects), count):
            kind = ("box", "sphere", "cylinder", "capsule")[k % 4]
            a, b = rng.uniform(0.5, 1.0, 2)
            if kind == "box":
                mesh = trimesh.creation.box(extents=(1.0, a, b))
            elif kind == "sphere":
                mesh = trimesh.creation.icosphere(subdivisions=3)
                mesh.apply_scale((1.0, a, b))
            elif kind == "cylinder":
                mesh = trimesh.creation.cylinder(radius=0.5 * a, height=1.0)
            else:
                mesh = trimesh.creation.capsule(radius=0.3 * a, height=1.0 - 0.6 * a)
            mesh.apply_scale(1.0 / (1.03 * np.linalg.norm(mesh.vertices, axis=1).max()))
            object_id = f"bench_{kind}_{k:03d}"
            write_asset(mesh, object_id, self.objects_dir, settings, {"source": "benchmark"}, convex_pieces=[mesh.convex_hull])
            self._objects[object_id] = True
        return sorted(self._objects)[:count]

    @property
    def objects_dir(self) -> Path:
        return self.workdir / "objects"


def approach_poses(count: int, scale: float, seed: int = 0) -> np.ndarray:
    """Palms 4-6 cm outside the object surface, facing its centre from random directions, fingers half closed."""
    from dexlite_pipeline.hand.rotation import matrix_to_euler_xyz

    rng = np.random.default_rng(seed)
    direction = rng.normal(size=(count, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    # The palm's normal is its local -y axis: align -y with -direction (pointing at the object).
    y_axis = direction
    helper = np.where(np.abs(y_axis[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    x_axis = np.cross(helper, y_axis)
    x_axis /= np.linalg.norm(x_axis, axis=1, keepdims=True)
    z_axis = np.cross(x_axis, y_axis)
    rotation = np.stack([x_axis, y_axis, z_axis], axis=2)
    pose = np.zeros((count, 28), np.float32)
    pose[:, :3] = direction * (scale + rng.uniform(0.04, 0.06, (count, 1))) - z_axis * 0.05
    pose[:, 3:6] = matrix_to_euler_xyz(torch.as_tensor(rotation, dtype=torch.float64)).numpy()
    pose[:, 6:] = rng.uniform(0.2, 0.6, (count, 22))
    return pose


def _grasps(object_ids: list[str], per_object: int, scale: float = 0.08):
    from dexlite_pipeline.io.grasp_store import GraspSet

    n = len(object_ids) * per_object
    return GraspSet(
        {
            "hand_pose": approach_poses(n, scale),
            "object_id": np.repeat(np.asarray(object_ids, dtype=object), per_object),
            "scale": np.full(n, scale, np.float32),
        }
    )


def bench_object_scaling(ctx: Context) -> list[Row]:
    """Wall time of energy evaluation and of the lift test for a fixed number of grasps per object, vs objects."""
    from dexlite_pipeline.energy.per_grasp import evaluate_grasp_energies

    try:
        from dexlite_pipeline.sim.config import LiftConfig
        from dexlite_pipeline.sim.lift import run_lift_tests
    except ImportError:
        run_lift_tests = None
    per_object = 2 if ctx.quick else 8
    evaluate_grasp_energies(_grasps(ctx.objects(1), 1), [ctx.objects_dir])  # one-time set-up (hand model) outside the timing
    rows = []
    for count in (2, 4) if ctx.quick else (8, 16, 32):
        grasps = _grasps(ctx.objects(count), per_object)
        start = time.perf_counter()
        evaluate_grasp_energies(grasps, [ctx.objects_dir])
        energy_s = time.perf_counter() - start
        label = f"wall time vs objects ({per_object} grasps/object)"
        rows.append(Row(label, f"{count} objects", energy_s, "s", "energies"))
        if run_lift_tests is not None:
            start = time.perf_counter()
            run_lift_tests(grasps, [ctx.objects_dir], LiftConfig(), 1)
            rows.append(Row(label, f"{count} objects", time.perf_counter() - start, "s", "lift test, 1 thread"))
    return rows


def external_benchmarks() -> dict[str, Callable[[Context], list[Row]]]:
    """``benchmarks/timing/bench_*.py`` modules of the other components, wrapped as benchmarks."""
    found = {}
    for path in sorted(BENCH_DIR.glob("bench_*.py")):

        def run(ctx: Context, path=path) -> list[Row]:
            spec = importlib.util.spec_from_file_location(path.stem, path)
            module = importlib.util.module_from_spec(spec)
            sys.modules[spec.name] = module
            spec.loader.exec_module(module)
            return [Row(**{k: r[k] for k in ("benchmark", "size", "value", "unit")}, note=str(r.get("note", ""))) for r in module.run(quick=ctx.quick)]

        found[path.stem.removeprefix("bench_")] = run
    return found


BENCHMARKS: dict[str, Callable[[Context], list[Row]]] = {
    "object_scaling": bench_object_scaling,
}


def run_benchmarks(quick: bool = False, only: list[str] | None = None, workdir: Path | None = None) -> list[Row]:
    """Run the chosen benchmarks; a component that is missing or fails gives a row saying so."""
    available = {**BENCHMARKS, **external_benchmarks()}
    names = only or list(available)
    unknown = sorted(set(names) - set(available))
    if unknown:
        raise ValueError(f"unknown benchmark(s) {', '.join(unknown)}; known: {', '.join(available)}")
    rows: list[Row] = []
    with tempfile.TemporaryDirectory(prefix="dexlite-bench-") as tmp:
        ctx = Context(Path(workdir or tmp), quick)
        for name in names:
            try:
                rows += available[name](ctx)
            except ImportError as exc:
                rows.append(Row(name, "-", math.nan, "-", f"not available: {exc}"))
            except Exception as exc:  # a broken component is reported in the table, the others still run
                rows.append(Row(name, "-", math.nan, "-", f"failed: {type(exc).__name__}: {exc}"))
    return rows


def machine_description() -> str:
    import os

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    gpu = torch.cuda.get_device_name(0) if torch.cuda.is_available() else "no GPU"
    return f"{cpu}; {os.cpu_count()} logical CPUs; torch {torch.__version__} ({torch.get_num_threads()} threads); {gpu}; Python {platform.python_version()}"


def format_table(rows: list[Row]) -> str:
    header = ("benchmark", "size", "value", "unit", "note")
    cells = [header] + [(r.benchmark, r.size, "n/a" if not np.isfinite(r.value) else f"{r.value:.4g}", r.unit, r.note) for r in rows]
    widths = [max(len(c[i]) for c in cells) for i in range(len(header))]
    lines = ["| " + " | ".join(c[i].ljust(widths[i]) for i in range(len(header))) + " |" for c in cells]
    lines.insert(1, "|" + "|".join("-" * (w + 2) for w in widths) + "|")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (seconds)")
    parser.add_argument("--only", nargs="+", help="run only these benchmarks")
    parser.add_argument("--threads", type=int, default=None, help="torch threads (default: torch's choice)")
    parser.add_argument("--csv", help="also write the rows to this CSV file")
    args = parser.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    machine = machine_description()  # before the modules change torch's thread count
    rows = run_benchmarks(quick=args.quick, only=args.only)
    print(f"Machine: {machine}")
    print(format_table(rows))
    if args.csv:
        import pandas as pd

        pd.DataFrame([asdict(r) for r in rows]).to_csv(args.csv, index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
