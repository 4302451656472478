"""Speed of this checkout's library against an earlier commit's, as ratios measured side by side.

    python benchmarks/timing/versus.py --base d39ef80 --objects RUN/results/objects            # energy step
    python benchmarks/timing/versus.py --base d39ef80 --objects RUN/results/objects --lift RUN/results/eval/sim/shard_000.zarr
    python benchmarks/timing/versus.py --base d39ef80 --objects RUN/results/objects --samples RUN/results/sample/shard_000.zarr

The machine is shared and its speed drifts, so absolute times mean little and two runs of
one code differ by 10-30%. This script measures both versions of the library in the same
run, alternating them (base, current, base, current, ...) in fresh processes, with the SAME
measuring code (this file) and the SAME inputs, and reports each case's ratio
current / base of the per-version minimum over rounds. The base library is the ``src/``
folder of ``--base`` (a commit, extracted with ``git archive`` into a temporary folder).

Cases (each a function of this module, run in a child process with one torch thread):

- ``energy_step``: CPU µs per grasp of one energy-and-gradient step (kinematics, every term,
  backward) at batches of 64, 256 and 1024, the post-optimization's weights and contacts,
  hands at the object: the poses come from ``--poses`` (made once by the current library
  from a short optimization on the first four objects of ``--objects``, so both versions
  evaluate the same poses).
- ``post``: CPU s per grasp of the post-optimization stage (each version's default ``post_optimize``
  settings, the random baseline off) on ``--post-grasps`` pure syntheses (``--sample-method``) spread evenly over a sample
  store (``--samples``, e.g. RUN/results/sample/shard_000.zarr), on their tables: the model path's refinement.
- ``optimize``: CPU s per grasp of optimization from scratch (each version's default ``optimize_grasps``
  settings, ``--optimize-grasps`` starts per object) on the first four objects of ``--objects`` at their real size
  where known, on their tables.
- ``ranking``: CPU s per kept grasp of the learned evaluator's ranking (``evaluator.ranking.rank_shard``: drawing the
  pool, scoring it) on one shard of a finished run with an evaluator (``--rank-run``, its ``config.yaml`` and
  ``--rank-seed``), after one warm-up call (the stage ranks in the process that just sampled).
- ``lift``: CPU s per tested grasp of the lift and six-direction tests (each version's default
  ``lift`` settings) on ``--lift-grasps`` grasps spread evenly over a grasp store (``--lift``), e.g. an
  evaluation shard of the default run: the realistic mix of outcomes.

The child prints one JSON line per measurement; the parent collects them.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BATCHES = (64, 256, 1024)


# ----------------------------------------------------------------------------- child side
def make_poses(objects_dir: str, out: str, count: int = 64, seed: int = 0) -> None:
    """Poses touching the first four objects of ``objects_dir`` (a short optimization), saved for both versions."""
    import numpy as np
    import torch

    from dexlite_pipeline.energy.config import EnergyConfig
    from dexlite_pipeline.energy.grasp_energy import GraspEnergy
    from dexlite_pipeline.hand.model import ShadowHand
    from dexlite_pipeline.objects.assets import load_asset, ok_object_ids
    from dexlite_pipeline.optim.annealing import optimize
    from dexlite_pipeline.optim.config import AnnealingConfig, InitConfig
    from dexlite_pipeline.optim.init import HullSampler, initial_poses

    torch.set_num_threads(1)
    ids = sorted(ok_object_ids([objects_dir]))[:4]
    assets = [load_asset([objects_dir], i) for i in ids]
    hand = ShadowHand()
    energy = GraspEnergy.from_assets(hand, assets, EnergyConfig(), max_scale=0.12)
    generator = torch.Generator().manual_seed(seed)
    object_index = torch.arange(count) % len(ids)
    scale = torch.tensor((0.08, 0.1, 0.12))[torch.arange(count) % 3]
    init = initial_poses(hand, HullSampler(assets), object_index, scale, InitConfig(distance_m=(0.06, 0.09)), generator)
    schedule = AnnealingConfig(iterations=300, step_size_period=6, temperature_period=4, final_contact_samples=256)
    result = optimize(energy, init, object_index, scale, schedule, generator)
    np.savez(out, object_ids=np.asarray(ids), hand_pose=result.hand_pose.numpy(), contact_index=result.contact_index.numpy(),
             object_index=object_index.numpy(), scale=scale.numpy())


def energy_step(objects_dir: str, poses: str, repeats: int = 7) -> list[dict]:
    """CPU µs per grasp and step at each batch size (minimum over ``repeats`` steps)."""
    import numpy as np
    import torch

    from dexlite_pipeline.energy.config import EnergyConfig
    from dexlite_pipeline.energy.grasp_energy import GraspEnergy
    from dexlite_pipeline.hand.model import ShadowHand
    from dexlite_pipeline.objects.assets import load_asset

    torch.set_num_threads(1)
    saved = np.load(poses)
    assets = [load_asset([objects_dir], str(i)) for i in saved["object_ids"]]
    energy = GraspEnergy.from_assets(ShadowHand(), assets, EnergyConfig(), max_scale=0.12)
    rows = []
    for batch in BATCHES:
        tile = -(-batch // len(saved["hand_pose"]))

        def tiled(name: str) -> torch.Tensor:
            value = torch.as_tensor(saved[name])
            return value.repeat(tile, *([1] * (value.dim() - 1)))[:batch]

        pose, contacts, index, scale = tiled("hand_pose"), tiled("contact_index").long(), tiled("object_index").long(), tiled("scale")

        def step() -> None:
            x = pose.clone().requires_grad_(True)
            result = energy(x, object_index=index, scale=scale, contact_index=contacts)
            torch.autograd.grad(result.total.sum(), x)

        step()
        times = []
        for _ in range(repeats):
            started = time.process_time()
            step()
            times.append(time.process_time() - started)
        rows.append({"case": "energy_step", "size": f"batch {batch}", "value": 1e6 * min(times) / batch, "unit": "CPU µs per grasp-step"})
    return rows


def lift(objects_dir: str, grasp_store: str, grasps: int) -> list[dict]:
    """CPU s per tested grasp of the lift and six-direction tests on ``grasps`` grasps spread evenly over ``grasp_store``,
    with the library's own default ``lift`` and ``scene`` sections (six directions on)."""
    import dataclasses

    import numpy as np
    import torch

    from dexlite_pipeline.config import default_config, from_section
    from dexlite_pipeline.io.grasp_store import read_grasp_store
    from dexlite_pipeline.sim.config import LiftConfig, SceneConfig
    from dexlite_pipeline.sim.lift import run_lift_tests
    from dexlite_pipeline.tabletop import load_support_planes

    torch.set_num_threads(1)
    config = default_config()
    lift_config = dataclasses.replace(from_section(LiftConfig, config.get("lift"), "config.lift"), six_directions=True)
    scene = from_section(SceneConfig, config.get("scene"), "config.scene")
    stored = read_grasp_store(grasp_store)
    chosen = stored.select(np.unique(np.linspace(0, len(stored) - 1, min(grasps, len(stored))).round().astype(int)))  # spread over the store's methods
    stability = Path(objects_dir).parent / "stability" / "stability.parquet"
    planes = load_support_planes(scene.table, str(stability))
    started = time.process_time()
    results = run_lift_tests(chosen, [objects_dir], lift_config, 1, support_planes=planes)
    seconds = time.process_time() - started
    held = int(np.asarray(results["lift_success"]).sum())
    return [{"case": "lift", "size": f"{len(chosen)} grasps", "value": seconds / len(chosen), "unit": "CPU s per grasp",
             "outcomes": {"held": np.asarray(results["lift_success"], bool).tolist(), "six": np.asarray(results["six_dir_success"], bool).tolist()}}]


def write_post_samples(sample_store: str, out: str, grasps: int, method: str = "cvae_raw") -> None:
    """``grasps`` pure syntheses (``method`` rows: ``cvae_raw``, or ``shipped_raw`` for the shipped model's) spread evenly over
    ``sample_store``, written as a store for both versions (labelled ``cvae_raw``, the rows the stage refines as samples)."""
    import numpy as np

    from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store, write_grasp_store

    stored = read_grasp_store(sample_store)
    raw = np.flatnonzero(np.asarray(stored.arrays["method"]).astype(str) == method)
    chosen = raw[np.unique(np.linspace(0, len(raw) - 1, min(grasps, len(raw))).round().astype(int))]
    arrays = {k: stored.arrays[k][chosen] for k in ("hand_pose", "object_id", "scale")}
    arrays["method"] = np.full(len(chosen), "cvae_raw", dtype=object)
    write_grasp_store(out, GraspSet(arrays, {}), {})


def post(objects_dir: str, samples: str) -> list[dict]:
    """CPU s per grasp of ``post_optimize_shard`` on the store ``samples`` (``write_post_samples``), the library's own default
    ``post_optimize`` (random baseline off), ``scene`` and ``energy`` sections; outcomes: each grasp ends within the start cap."""
    import dataclasses

    import numpy as np
    import torch

    from dexlite_pipeline.config import default_config, from_section
    from dexlite_pipeline.optim.config import PostOptimizeConfig
    from dexlite_pipeline.optim.post_shard import post_optimize_shard
    from dexlite_pipeline.sim.config import SceneConfig

    torch.set_num_threads(1)
    config = default_config()
    settings = dataclasses.replace(from_section(PostOptimizeConfig, config.get("post_optimize"), "config.post_optimize"), random_baseline=False)
    scene = from_section(SceneConfig, config.get("scene"), "config.scene")
    stability = Path(objects_dir).parent / "stability" / "stability.parquet"
    margin_m = float(config["energy"]["self_penetration_margin_m"])
    started = time.process_time()
    (refined, attrs), _ = post_optimize_shard(samples, [objects_dir], 0, post_optimize=settings, self_penetration_margin_m=margin_m, scene=scene,
                                              seed=0, device="cpu", stability_path=str(stability))
    seconds = time.process_time() - started
    within = (np.asarray(refined.arrays["penetration_mm"]) <= 2.0).tolist()
    return [{"case": "post", "size": f"{len(refined)} grasps", "value": seconds / len(refined), "unit": "CPU s per grasp (stage)",
             "optimizer_value": attrs["seconds_per_grasp"], "outcomes": {"within 2 mm": within}}]


def optimize_from_scratch(objects_dir: str, grasps_per_object: int) -> list[dict]:
    """CPU s per grasp of ``optim.from_scratch.synthesize`` on the first four objects of ``objects_dir`` (real size where
    known, else the configured scales), the library's own default ``optimize_grasps``, ``energy`` and ``scene`` sections."""
    import dataclasses

    import numpy as np
    import torch

    from dexlite_pipeline.config import default_config, from_section
    from dexlite_pipeline.energy.config import EnergyConfig
    from dexlite_pipeline.objects.assets import load_asset, ok_object_ids
    from dexlite_pipeline.optim.config import OptimizeGraspsConfig
    from dexlite_pipeline.optim.from_scratch import synthesize
    from dexlite_pipeline.sim.config import SceneConfig
    from dexlite_pipeline.tabletop import load_support_planes

    torch.set_num_threads(1)
    config = default_config()
    settings = dataclasses.replace(from_section(OptimizeGraspsConfig, config.get("optimize_grasps"), "config.optimize_grasps"),
                                   grasps_per_object=grasps_per_object)
    energy_config = from_section(EnergyConfig, config.get("energy"), "config.energy")
    scene = from_section(SceneConfig, config.get("scene"), "config.scene")
    assets = [load_asset([objects_dir], i) for i in sorted(ok_object_ids([objects_dir]))[:4]]
    planes = load_support_planes(scene.table, str(Path(objects_dir).parent / "stability" / "stability.parquet"))
    scales = [(a.real_scale,) if a.real_scale else tuple(settings.scales) for a in assets]
    started = time.process_time()
    grasps, _ = synthesize(assets, settings, energy_config, torch.Generator().manual_seed(0), "cpu", support_planes=planes, object_scales=scales)
    seconds = time.process_time() - started
    within = (np.asarray(grasps.arrays["penetration_mm"]) <= 2.0).tolist()
    return [{"case": "optimize", "size": f"{len(grasps)} grasps", "value": seconds / len(grasps), "unit": "CPU s per grasp",
             "outcomes": {"within 2 mm": within}}]


def ranking(run: str, seed: int, shard: int = 0) -> list[dict]:
    """CPU s per kept grasp of ``rank_shard`` on shard ``shard`` of ``run`` (its sample store without its ranked rows)."""
    import numpy as np
    import torch
    import yaml

    from dexlite_pipeline.evaluator.ranking import rank_shard
    from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store
    from dexlite_pipeline.settings import build_config

    torch.set_num_threads(1)
    config = build_config({**yaml.safe_load(Path(run, "config.yaml").read_text()), "seed": seed})
    stored = read_grasp_store(f"{run}/results/sample/shard_{shard:03d}.zarr")
    unranked = np.asarray(stored.arrays["method"]).astype(str) != "cvae_ranked"
    added = ("evaluator_score", "evaluator_kept_fraction", "evaluator_rank")
    sampled = GraspSet({k: v[unranked] for k, v in stored.arrays.items() if k not in added}, stored.attrs)
    arguments = (sampled, f"{run}/results/model/cvae.pt", f"{run}/results/evaluator/evaluator.pt", [f"{run}/results/objects"],
                 f"{run}/results/stability/stability.parquet", shard)
    options = dict(shards=config.shards, sample=config.sample, section=config.evaluator, diversity=config.diversity, table=config.scene.table,
                   seed=seed, device="cpu")
    rank_shard(*arguments, **options)  # warm-up
    _, attrs = rank_shard(*arguments, **options)
    return [{"case": "ranking", "size": f"{attrs['pool']} pooled", "value": attrs["cpu_seconds"] / attrs["kept"], "unit": "CPU s per kept grasp"}]


# ----------------------------------------------------------------------------- parent side
def extract_source(ref: str, destination: Path) -> Path:
    """``ref``'s ``src/`` folder extracted into ``destination`` (returned: the folder to put on PYTHONPATH)."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", ref, "src"], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(destination)], input=archive, check=True)
    return destination / "src"


def run_child(source: Path, call: str) -> list[dict]:
    """Run ``call`` (Python source evaluating to a list of rows) in a fresh process on the library at ``source``."""
    code = f"import json, sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); import versus; print('ROWS', json.dumps({call}))"
    env = {**os.environ, "PYTHONPATH": str(source), "OMP_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{source}: {call} failed:\n{done.stderr[-3000:]}")
    line = next(line for line in done.stdout.splitlines() if line.startswith("ROWS "))
    return json.loads(line[5:])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--base", required=True, help="commit whose library is the baseline")
    parser.add_argument("--objects", required=True, help="prepared objects (a run's results/objects)")
    parser.add_argument("--lift", help="grasp store to lift-test (e.g. RUN/results/eval/sim/shard_000.zarr); omit to skip the case")
    parser.add_argument("--lift-grasps", type=int, default=200)
    parser.add_argument("--samples", help="sample store whose pure syntheses to post-optimize (e.g. RUN/results/sample/shard_000.zarr); omit to skip")
    parser.add_argument("--post-grasps", type=int, default=256)
    parser.add_argument("--sample-method", default="cvae_raw", help="the sample rows the post case refines (shipped_raw: the shipped model's)")
    parser.add_argument("--optimize-grasps", type=int, default=0, help="starts per object of the optimize case (0: skip it)")
    parser.add_argument("--rank-run", help="a finished run with a learned evaluator whose shard 000 the ranking case ranks; omit to skip")
    parser.add_argument("--rank-seed", type=int, default=0, help="the rank run's seed")
    parser.add_argument("--rounds", type=int, default=3, help="alternations of base and current")
    parser.add_argument("--out", help="write the table as JSON here too")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory(prefix="versus_") as scratch:
        base = extract_source(args.base, Path(scratch))
        current = ROOT / "src"
        poses = str(Path(scratch) / "poses.npz")
        run_child(current, f"versus.make_poses({args.objects!r}, {poses!r}) or []")
        calls = [f"versus.energy_step({args.objects!r}, {poses!r})"]
        if args.lift:
            calls.append(f"versus.lift({args.objects!r}, {args.lift!r}, {args.lift_grasps})")
        if args.samples:
            samples = str(Path(scratch) / "post_samples.zarr")
            run_child(current, f"versus.write_post_samples({args.samples!r}, {samples!r}, {args.post_grasps}, {args.sample_method!r}) or []")
            calls.append(f"versus.post({args.objects!r}, {samples!r})")
        if args.rank_run:
            calls.append(f"versus.ranking({args.rank_run!r}, {args.rank_seed})")
        if args.optimize_grasps:
            calls.append(f"versus.optimize_from_scratch({args.objects!r}, {args.optimize_grasps})")
        best: dict[tuple[str, str, str], dict] = {}
        for round_number in range(args.rounds):
            for version, source in (("base", base), ("current", current)):
                for call in calls:
                    for row in run_child(source, call):
                        key = (version, row["case"], row["size"])
                        if key not in best or row["value"] < best[key]["value"]:
                            best[key] = row
                print(f"round {round_number + 1}/{args.rounds}: {version} done", file=sys.stderr, flush=True)
    table = []
    for (version, case, size), row in sorted(best.items()):
        if version != "current":
            continue
        before = best[("base", case, size)]
        table.append({"case": case, "size": size, "base": before["value"], "current": row["value"], "unit": row["unit"],
                      "ratio": row["value"] / before["value"], "base_row": before, "current_row": row})
    print(f"| case | size | base ({args.base}) | current | unit | current / base |\n| --- | --- | ---: | ---: | --- | ---: |")
    for row in table:
        print(f"| {row['case']} | {row['size']} | {row['base']:.4g} | {row['current']:.4g} | {row['unit']} | {row['ratio']:.2f} |")
    for row in table:  # outcomes of the same grasps under both versions
        for name, before in row["base_row"].get("outcomes", {}).items():
            after = row["current_row"]["outcomes"][name]
            agree = sum(a == b for a, b in zip(before, after))
            print(f"{row['case']}, {name}: {sum(before)} / {sum(after)} of {len(before)} (base / current); the two agree on {agree} ({100 * agree / len(before):.1f}%)")
    if args.out:
        Path(args.out).write_text(json.dumps(table, indent=1))


if __name__ == "__main__":
    main()
