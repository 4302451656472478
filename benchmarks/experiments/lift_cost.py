"""CPU seconds per tested grasp of the lift and six-direction tests on a dataset batch's grasps, with a digest of outcomes.

    python benchmarks/experiments/lift_cost.py --objects-dir /tmp/liftcost/objects --out /tmp/liftcost/after.npz

Takes the grasps of a few objects of one dataset batch (default: batch 0013, the first instance of each family in
it, ``--per-object`` grasps each, in dataset order), rebuilds those objects from their ids into ``--objects-dir`` (the
household generator and the default ``objects`` preparation settings; reused when already there), puts each on the
table of its resting pose in the dataset's objects.csv and runs ``sim.lift.run_lift_tests`` on one thread with the
batch's own ``lift`` config. Prints the process CPU seconds of that call per tested grasp (objects prepared, modules
imported and the hand built before the clock starts), the held and six-direction counts, and two SHA-256 digests: of
the outcome flags and failure reasons, and of those plus the float32 lift ratios and six-direction translations and
rotations byte for byte. ``--out`` writes the arrays (.npz) so that two checkouts' outcomes can be compared value for
value (``--compare A.npz B.npz``). To measure another commit, run this file with ``PYTHONPATH`` pointing at that
commit's ``src`` (a ``git worktree``).
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

FLAG_ARRAYS = ("lift_success", "six_dir_success", "six_dir_passed", "failure_reason")
VALUE_ARRAYS = ("lift_ratio", "six_dir_translation_m", "six_dir_rotation_deg", "initial_penetration_mm", "initial_hull_overlap_mm")


def digest(results: dict, names) -> str:
    """SHA-256 (first 16 hex digits) of the named result arrays' bytes (strings as UTF-8, one per line)."""
    h = hashlib.sha256()
    for name in names:
        values = np.asarray(results[name])
        h.update(name.encode())
        if values.dtype == object or values.dtype.kind in "US":
            h.update("\n".join(str(v) for v in values).encode())
        else:
            h.update(np.ascontiguousarray(values).tobytes())
    return h.hexdigest()[:16]


class StepClock:
    """Within its ``with`` block, counts MuJoCo's ``mj_step`` calls and simulation steps and the CPU seconds spent in them
    (``mujoco.mj_step`` is wrapped; the simulator looks it up at each call), and hashes the state (``qpos``, ``qvel``,
    float64) after every call: two versions that simulate the same grasps the same way take the same steps and have the
    same ``trajectory`` digest, bit for bit, when every control chunk's state is identical."""

    def __init__(self) -> None:
        self.seconds, self.steps, self.calls = 0.0, 0, 0
        self.hash = hashlib.sha256()

    @property
    def trajectory(self) -> str:
        return self.hash.hexdigest()[:16]

    def __enter__(self) -> "StepClock":
        import mujoco

        self._step = step = mujoco.mj_step
        clock = time.process_time

        def counted(m, d, nstep=1):
            t = clock()
            step(m, d, nstep=nstep)
            self.seconds += clock() - t
            self.steps += nstep
            self.calls += 1
            self.hash.update(d.qpos.tobytes())
            self.hash.update(d.qvel.tobytes())

        mujoco.mj_step = counted
        return self

    def __exit__(self, *exc) -> None:
        import mujoco

        mujoco.mj_step = self._step


PHASES = (  # (module, attribute path, label): the parts of run_lift_tests that --phases clocks
    ("mujoco", "mj_step", "mj_step (the physics)"),
    ("dexlite_pipeline.sim.simulator", "GraspSimulator.lift", "lift test: Python between steps, resets"),
    ("dexlite_pipeline.sim.simulator", "GraspSimulator.six_directions", "six directions: Python between steps, resets"),
    ("dexlite_pipeline.sim.simulator", "GraspSimulator.initial_contact_depth_m", "start overlap with the convex pieces"),
    ("dexlite_pipeline.sim.lift", "_squeeze_plans", "squeeze targets (torch)"),
    ("dexlite_pipeline.sim.lift", "start_depth_m", "start depth against the mesh (torch)"),
    ("dexlite_pipeline.sim.lift", "hand_table_depth", "hand below the table (torch)"),
    ("dexlite_pipeline.energy.grasp_energy", "GraspEnergy.from_assets", "depth measure, built once per object"),
    ("dexlite_pipeline.sim.scene", "LiftScene.build", "scene compiled once per object"),
)


class PhaseClock:
    """Within its ``with`` block, the CPU seconds spent in each of ``PHASES`` less those of the phases it calls (each
    function is replaced by a clocked wrapper and put back on exit), and the number of calls."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {label: 0.0 for _, _, label in PHASES}
        self.calls: dict[str, int] = {label: 0 for _, _, label in PHASES}
        self._saved: list[tuple[object, str, object]] = []

    def __enter__(self) -> "PhaseClock":
        import importlib

        inner: list[float] = []  # per active phase, the seconds of the phases it called

        def clocked(function, label):
            def wrapper(*args, **kwargs):
                start = time.process_time()
                inner.append(0.0)
                try:
                    return function(*args, **kwargs)
                finally:
                    spent = time.process_time() - start
                    self.seconds[label] += spent - inner.pop()
                    self.calls[label] += 1
                    if inner:
                        inner[-1] += spent
            return wrapper

        for module, path, label in PHASES:
            *owners, name = path.split(".")
            owner = importlib.import_module(module)
            for part in owners:
                owner = getattr(owner, part)
            self._saved.append((owner, name, vars(owner)[name] if isinstance(owner, type) else getattr(owner, name)))
            setattr(owner, name, clocked(getattr(owner, name), label))
        return self

    def __exit__(self, *exc) -> None:
        for owner, name, original in reversed(self._saved):
            setattr(owner, name, original)

    def table(self, total: float, tested: int) -> str:
        rows = [f"| {label} | {seconds:.2f} | {100 * seconds / total:.1f}% | {self.calls[label]} | {1000 * seconds / max(tested, 1):.2f} |"
                for label, seconds in sorted(self.seconds.items(), key=lambda item: -item[1])]
        rest = total - sum(self.seconds.values())
        rows.append(f"| the rest (first calls' imports, bookkeeping) | {rest:.2f} | {100 * rest / total:.1f}% | | {1000 * rest / max(tested, 1):.2f} |")
        return "\n".join(["| part | CPU s | share | calls | ms per tested grasp |", "| --- | ---: | ---: | ---: | ---: |", *rows])


def chosen_objects(objects_table, batch: int, count: int) -> list[str]:
    """The first instance of each family among the batch's objects, in family order, up to ``count``."""
    from dexlite_pipeline.dataset.layout import object_family

    rows = objects_table[objects_table["batch"].astype(int) == batch]
    first: dict[str, str] = {}
    for object_id, source in sorted(zip(rows["object_id"], rows["source"])):
        first.setdefault(object_family(object_id, source), object_id)
    return [first[f] for f in sorted(first)][:count]


def prepare(object_ids: list[str], objects_dir: Path) -> None:
    """Rebuild the objects from their ids into ``objects_dir`` with the default preparation settings (seed 0)."""
    from dexlite_pipeline.objects.config import ObjectsConfig
    from dexlite_pipeline.objects.prepare import builder_version, prepare_object
    from dexlite_pipeline.objects.sources import rebuilt_source_of

    settings = ObjectsConfig().build_settings(0)
    for object_id in object_ids:
        if (objects_dir / "assets" / object_id / "arrays.zarr").exists():
            continue
        row = prepare_object(rebuilt_source_of(object_id, objects_dir / "meshes"), str(objects_dir), settings, builder_version())
        if row["status"] != "ok":
            raise SystemExit(f"{object_id}: not prepared: {row.get('reason')}")


def measure(args) -> dict:
    import torch

    from dexlite_pipeline.dataset.store import load_dataset, read_objects
    from dexlite_pipeline.hand.model import ShadowHand
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.objects.rest_pose import SupportPlane
    from dexlite_pipeline.sim.config import lift_config_from
    from dexlite_pipeline.sim.lift import run_lift_tests
    from dexlite_pipeline.tabletop import SupportPlanes

    torch.set_num_threads(1)
    dataset = Path(args.dataset)
    objects_table = read_objects(dataset)
    object_ids = args.object_ids or chosen_objects(objects_table, args.batch, args.objects)
    objects_dir = Path(args.objects_dir)
    prepare(object_ids, objects_dir)
    grasps, objects = load_dataset(dataset, object_ids)
    in_batch = np.asarray(grasps.arrays["batch"]) == args.batch
    rows = []
    for object_id in object_ids:
        mine = np.flatnonzero(in_batch & (grasps.object_id.astype(str) == object_id))
        real = load_asset([str(objects_dir)], object_id).real_scale
        scale = np.asarray(grasps.scale[mine], np.float64)
        if real and np.abs(scale / real - 1.0).max() > 1e-3:
            raise SystemExit(f"{object_id}: the dataset's scale {scale.min():.5g} is not the prepared object's {real:.5g}")
        rows.extend(mine[: args.per_object].tolist())
    chosen = grasps.select(np.asarray(rows))
    planes = SupportPlanes({
        row["object_id"]: SupportPlane((float(row["support_nx"]), float(row["support_ny"]), float(row["support_nz"])), float(row["support_offset"]))
        for row in objects.to_dict("records")
    })
    config = lift_config_from(json.loads((dataset / "configs" / f"batch_{args.batch:04d}.json").read_text()))
    hand = ShadowHand()
    stepping, phases = StepClock(), PhaseClock() if args.phases else contextlib.nullcontext()
    start = time.process_time()
    with stepping, phases:
        results = run_lift_tests(chosen, [str(objects_dir)], config, 1, support_planes=planes, hand=hand)
    seconds = time.process_time() - start
    tested = int(np.isfinite(np.asarray(results["lift_ratio"], np.float64)).sum())
    return {"object_ids": object_ids, "grasps": len(chosen), "tested": tested, "seconds": seconds, "results": results,
            "stored_held": np.asarray(chosen.arrays["lift_success"], bool), "step_seconds": stepping.seconds, "steps": stepping.steps,
            "step_calls": stepping.calls, "trajectory": stepping.trajectory, "phases": phases if args.phases else None}


def compare(a_path: str, b_path: str) -> int:
    """Print, per array, whether two saved outcomes are equal and the largest difference; 0 when every flag agrees."""
    a, b = np.load(a_path, allow_pickle=True), np.load(b_path, allow_pickle=True)
    flags_equal = True
    for name in FLAG_ARRAYS + VALUE_ARRAYS:
        x, y = a[name], b[name]
        if x.dtype.kind == "f":
            both_nan = np.isnan(x) & np.isnan(y)
            diff = np.where(both_nan, 0.0, np.abs(x.astype(np.float64) - y.astype(np.float64)))
            print(f"{name}: {'identical' if np.array_equal(x, y, equal_nan=True) else 'differ'}; max |difference| {np.nanmax(diff):.3g}")
        else:
            same = np.array_equal(x, y)
            flags_equal &= same
            print(f"{name}: {'identical' if same else f'{int((x != y).sum())} differ'}")
    return 0 if flags_equal else 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="dataset", help="grasp dataset folder")
    parser.add_argument("--batch", type=int, default=13, help="the batch whose grasps and lift config are used")
    parser.add_argument("--objects", type=int, default=6, help="objects: the first instance of each family in the batch")
    parser.add_argument("--object-ids", nargs="*", help="these objects instead")
    parser.add_argument("--per-object", type=int, default=40, help="grasps per object (the first in dataset order)")
    parser.add_argument("--objects-dir", default="/tmp/liftcost/objects", help="prepared objects (made when missing)")
    parser.add_argument("--out", help="write the outcome arrays here (.npz)")
    parser.add_argument("--phases", action="store_true", help="also split the CPU time by part (clocked wrappers: a little slower)")
    parser.add_argument("--profile", help="write a cProfile of the lift tests here (.prof); its CPU time is then not comparable")
    parser.add_argument("--compare", nargs=2, metavar=("A", "B"), help="compare two --out files instead of measuring")
    args = parser.parse_args(argv)
    if args.compare:
        return compare(*args.compare)
    if args.profile:
        import cProfile

        profiler = cProfile.Profile()
        report = profiler.runcall(measure, args)
        profiler.dump_stats(args.profile)
    else:
        report = measure(args)
    results = report["results"]
    held = int(np.asarray(results["lift_success"], bool).sum())
    six = int(np.asarray(results["six_dir_success"], bool).sum())
    agree = float((np.asarray(results["lift_success"], bool) == report["stored_held"]).mean())
    print(f"objects: {', '.join(report['object_ids'])}")
    print(f"grasps: {report['grasps']}, tested (simulated): {report['tested']}, held: {held}, held and six directions: {six}")
    print(f"held as stored in the dataset: {int(report['stored_held'].sum())} (this run agrees on {100 * agree:.1f}% of grasps)")
    print(f"CPU s: {report['seconds']:.2f}; per tested grasp: {report['seconds'] / max(report['tested'], 1):.4f}")
    outside = report["seconds"] - report["step_seconds"]
    print(f"inside mj_step: {report['step_seconds']:.2f} CPU s ({report['steps']} steps in {report['step_calls']} calls, "
          f"{1e6 * report['step_seconds'] / max(report['steps'], 1):.1f} us per step); outside: {outside:.2f} CPU s, "
          f"{outside / max(report['tested'], 1):.4f} per tested grasp")
    if report["phases"] is not None:
        print(report["phases"].table(report["seconds"], report["tested"]))
    print(f"digest of the state after every mj_step call (qpos, qvel): {report['trajectory']}")
    print(f"digest of flags and reasons: {digest(results, FLAG_ARRAYS)}")
    print(f"digest of flags, reasons and values: {digest(results, FLAG_ARRAYS + VALUE_ARRAYS)}")
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        np.savez(args.out, **{name: np.asarray(results[name]) for name in FLAG_ARRAYS + VALUE_ARRAYS})
    return 0


if __name__ == "__main__":
    sys.exit(main())
