"""Generators side by side on the same data: the CVAE (``train.generator: cvae``) against conditional flow matching
(``flow``), or the CVAE with the surface-sample terms in its loss (``cvae+surface``: ``train.weight_surface_penetration``
= ``--surface-penetration-weight``, ``train.weight_surface_distance`` = ``--surface-distance-weight``), trained with the
same budget on the same grasps and measured on the same held-out objects.

    python benchmarks/experiments/generator_side_by_side.py OUT --objects OBJECTS_DIR [--dataset dataset] [--train-objects 84]
        [--steps 3000] [--seeds 0 1] [--heldout 12 | --heldout-ids ID ...] [--n 16] [--families cvae flow cvae+surface]
        [--surface-penetration-weight 0] [--surface-distance-weight 0] [--train-json JSON] [--modes raw "backed out" refined]
        [--threads 1]

Training data: the held grasps of the repository's grasp dataset (``dataset.load_dataset``) on the training objects prepared
in ``OBJECTS_DIR`` (a ``dexlite prepare-objects`` output whose catalog lists household training objects the dataset holds;
``--train-objects K``: a seeded subset of K of them, the same for every family and seed). Each family is trained with the
pipeline's default section ``train`` (config.yaml; ``--train-json``: keys of that section over it, for every family, e.g.
the networks' sizes), ``max_steps`` = ``--steps`` and ``seed`` = the seed, on one torch thread; the training grasps,
batches and validation split are the same for every family at a seed. Models go to ``OUT/seed_<s>/<family>.pt``.

Held-out objects: the first ``--heldout`` objects of the household split (``objects/household_split.yaml``; the first
twelve are instance 900 of each of the twelve families), never in the dataset, or ``--heldout-ids`` (e.g. instances of no
split and no dataset batch, to choose a setting on objects other than those it is then measured on), each turned about
the vertical through its bounding-box centre by a yaw from ``default_rng([seed, crc32(object id)])`` (so every family at
a seed sees the same turned objects). Each model samples ``--n`` grasps per object through ``dexlite_pipeline.api.grasp``
(the path of ``dexlite grasp``: real size, heading match, neighbour codes and matched anchors, starts raised above the
table), with no learned evaluator and no optimization top-up, in each of ``--modes``: *raw* (the samples as drawn: no
optimizer step and no contact resolution), *backed out* (raw, then only contact resolution, the post-optimization's last
phase, which moves a sample deeper than ``post_optimize.resolve_penetration_to_m`` back out of the object) and *refined*
(the default post-optimization). Every grasp is lift-tested on the table with the 2 mm start cap.

Writes ``OUT/side_by_side_seed<seeds>.csv`` (one row per seed, family, mode and object: attempts, held, distinct held, median start
depth in mm, training seconds) and prints, and writes to ``OUT/side_by_side.md``, per family and mode with seeds pooled
and per seed: held per attempt with a Wilson 95% interval, mean distinct held grasps per object, and the median over objects
of each object's median start depth over its tested attempts (mm; a sample that starts deeper than 2 mm inside the
object fails the lift test; refined grasps that post-optimization stopped as hopeless are not tested). ``--tabulate``
pools the CSVs of several calls (seeds run in parallel) into ``OUT/side_by_side.md``. ``--in-distribution K`` adds raw
samples on K of the training objects as generated (one per family): how each family does where it has seen data.
``--reuse-models --skip-heldout --in-distribution K`` measures only that, on the models an earlier call trained.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

# raw: the samples as drawn (no optimizer step, no contact resolution; only the tabletop's raise above the table);
# backed out: raw, then only the post-optimization's last phase, contact resolution (post_optimize.resolve_penetration_to_m:
# each sample deeper than 1.5 mm moved back out of the object); refined: the default post-optimization.
MODES = {"raw": {"post_optimize": {"annealing": {"iterations": 0}, "resolve_penetration_to_m": 0.0}},
         "backed out": {"post_optimize": {"annealing": {"iterations": 0}}}, "refined": {}}
TRAINING_OBJECTS_MODE = "raw on training objects"  # --in-distribution: raw samples on objects the models trained on


def training_grasps(dataset_dir: Path, objects_dir: Path, count: int):
    """(GraspSet of the held dataset grasps, sorted object ids): the dataset's held grasps on a seeded subset of ``count`` of
    the prepared training objects it holds (seed 0: the same subset whatever the training seed)."""
    import pandas as pd

    from dexlite_pipeline.dataset.store import load_dataset, present_objects
    from dexlite_pipeline.io.grasp_store import GRASP_TYPE, GraspSet
    from dexlite_pipeline.model.trainer import training_object_subset

    catalog = pd.read_parquet(objects_dir / "catalog.parquet")
    prepared = set(catalog.loc[(catalog["split"] == "train") & (catalog["status"] == "ok"), "object_id"].astype(str))
    ids = sorted(training_object_subset(prepared & present_objects(dataset_dir), count, 0))
    grasps, _ = load_dataset(dataset_dir, ids, held_only=True)
    arrays = {k: grasps.arrays[k] for k in ("hand_pose", "object_id", "scale", GRASP_TYPE)}
    arrays["contact_index"] = np.full((len(grasps), 4), -1, np.int64)  # the dataset keeps no contacts (read by weighted energies only)
    return GraspSet(arrays, {}), sorted(set(grasps.object_id.tolist()))


def train_family(family: str, grasps, object_ids: list[str], objects_dir: Path, steps: int, seed: int, path: Path,
                 surface_weights: tuple[float, float] = (0.0, 0.0), train_overlay: dict | None = None) -> float:
    """Train one family on ``grasps`` with the default section ``train`` (with ``train_overlay`` over it: keys of the
    section, as a config file would give them) at ``steps`` and ``seed``, write the model file to ``path``; returns the
    training's CPU-seconds. ``cvae+surface``: the CVAE with the surface-sample terms in its loss at weights
    ``surface_weights`` (``train.weight_surface_penetration``, ``train.weight_surface_distance``)."""
    import torch

    from dexlite_pipeline.config import load_config, merge_config
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.model.checkpoint import save_checkpoint
    from dexlite_pipeline.model.data import build_training_data, split_validation
    from dexlite_pipeline.model.surface_terms import surface_terms
    from dexlite_pipeline.model.trainer import unbuilt_energy_terms
    from dexlite_pipeline.model.training import fit_training_codes, train_cvae, with_surface_terms
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.settings import build_config

    repository = Path(__file__).resolve().parents[2]
    penetration, distance = surface_weights if family.endswith("+surface") else (0.0, 0.0)
    mapping = merge_config(load_config(repository / "config.yaml"), {"train": train_overlay or {}})
    config = dataclasses.replace(build_config(mapping).train, max_steps=steps, seed=seed,
                                 generator=family.split("+")[0], weight_surface_penetration=penetration, weight_surface_distance=distance)
    start = time.process_time()
    hand = ShadowHand("cpu")
    assets = [load_asset([str(objects_dir)], oid) for oid in object_ids]
    data = build_training_data(grasps, assets, hand, "cpu")
    train_index, val_index = split_validation(len(grasps), config.validation_fraction, seed)
    energy_terms = None
    if config.surface_terms():
        surface = surface_terms(hand, data.clouds, config.surface_terms(), training_grasps=len(data.pose_features))
        energy_terms = with_surface_terms(unbuilt_energy_terms, surface, mesh=False)
    result = train_cvae(data, train_index, val_index, config, energy_terms, seed)
    fit = fit_training_codes(result.model, data, train_index, config)
    last = result.history[-1]
    print(f"{family} seed {seed}: {result.steps} steps, train recon {last['train_recon']:.4g}, val recon {last.get('val_recon', float('nan')):.4g}, "
          f"fit rotation {fit['rotation_error_deg_median']:.2f} deg, translation {fit['translation_error_mm_median']:.2f} mm", flush=True)
    seconds = time.process_time() - start
    save_checkpoint(path, result.model, config, {"seed": seed, "steps": result.steps, "train_object_ids": object_ids, "fit": fit,
                                                 "train_grasps": int(len(train_index)), "torch_version": torch.__version__},
                    training_grasps={"hand_pose": grasps.hand_pose[train_index], "object_id": grasps.object_id[train_index],
                                     "scale": grasps.scale[train_index]})  # fmt: skip
    return seconds


def heldout_meshes(count: int, seed: int, object_ids: list[str] | None = None) -> dict:
    """The first ``count`` household-split objects (or ``object_ids``), each turned about the vertical by its seeded yaw
    (the first yaw of ``yaw_sensitivity.py`` for the seed): {object id: mesh}."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from yaw_sensitivity import turned_about_vertical, yaws_of

    from dexlite_pipeline.objects.household import household_object
    from dexlite_pipeline.objects.sources import household_benchmark_list

    ids = object_ids or household_benchmark_list()[:count]
    return {oid: turned_about_vertical(household_object(oid).mesh, float(yaws_of(oid, seed, 1)[0])) for oid in ids}


def training_meshes(object_ids: list[str], count: int) -> dict:
    """``count`` of the training objects as generated, the first of each family in id order, families in turn."""
    from dexlite_pipeline.objects.household import household_object, parse_household_id

    firsts = {}
    for oid in sorted(object_ids):
        firsts.setdefault(parse_household_id(oid)[0], oid)
    return {oid: household_object(oid).mesh for oid in list(firsts.values())[:count]}


def evaluate(model: Path, meshes: dict, n: int, seed: int, mode: str, out_dir: Path, threads: int) -> list[dict]:
    """One ``api.grasp`` call of ``model`` on ``meshes`` in ``mode`` (of ``MODES``): per object attempts, held, distinct
    held grasps and the median start depth over its tested attempts (mm)."""
    from dexlite_pipeline.api import grasp
    from dexlite_pipeline.io.grasp_store import read_grasp_store

    result = grasp(meshes, n=n, seed=seed, out_dir=out_dir, model=str(model), evaluator=None, min_distinct=0, upright_axis="+z",
                   config=MODES[mode], threads=threads, overwrite=True)  # fmt: skip
    every = read_grasp_store(out_dir / "all_grasps.zarr")
    depth = np.asarray(every.arrays["initial_penetration_mm"], np.float64)
    rows = []
    for name, mesh in result.meshes.items():
        mine = every.object_id == name
        rows.append({"object_id": name.removeprefix("user-"), "attempts": mesh.attempts, "held": mesh.held,
                     "distinct": int(len(mesh.hand_pose)), "start_depth_mm_median": float(np.nanmedian(depth[mine])) if np.isfinite(depth[mine]).any() else np.nan})
    return rows


def summary_table(rows: list[dict]) -> list[str]:
    """Markdown rows per family and mode: held / attempts, rate with its Wilson 95% interval, distinct per object, depth."""
    import warnings

    from dexlite_pipeline.evaluation.rates import wilson_interval

    warnings.filterwarnings("ignore", "All-NaN slice|Mean of empty slice", RuntimeWarning)

    lines = ["| family | mode | held / attempts | held per attempt (95% CI) | distinct held per object | median start depth (mm) | training CPU-s |",
             "| --- | --- | --- | --- | --- | --- | --- |"]  # fmt: skip
    for family in dict.fromkeys(r["family"] for r in rows):
        for mode in (*MODES, TRAINING_OBJECTS_MODE):
            group = [r for r in rows if r["family"] == family and r["mode"] == mode]
            if not group:
                continue
            held, attempts = sum(r["held"] for r in group), sum(r["attempts"] for r in group)
            flags = np.r_[np.ones(held, bool), np.zeros(attempts - held, bool)]
            low, high = wilson_interval(flags)
            depth = np.nanmedian([r["start_depth_mm_median"] for r in group])
            train_s = np.nanmean(list({r["seed"]: r["training_cpu_s"] for r in group}.values()) or [np.nan])
            lines.append(f"| {family} | {mode} | {held} / {attempts} | {100 * held / max(attempts, 1):.1f}% ({100 * low:.1f}–{100 * high:.1f}) | "
                         f"{np.mean([r['distinct'] for r in group]):.2f} | {depth:.2f} | {train_s:.0f} |")  # fmt: skip
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("--objects", type=Path, required=True, help="prepared training objects (dexlite prepare-objects output folder)")
    parser.add_argument("--dataset", type=Path, default=Path(__file__).resolve().parents[2] / "dataset")
    parser.add_argument("--train-objects", type=int, default=84)
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--heldout", type=int, default=12)
    parser.add_argument("--n", type=int, default=16)
    parser.add_argument("--families", nargs="+", default=["cvae", "flow"], choices=["cvae", "flow", "cvae+surface"])
    parser.add_argument("--surface-penetration-weight", type=float, default=0.0, help="cvae+surface: train.weight_surface_penetration")
    parser.add_argument("--surface-distance-weight", type=float, default=0.0, help="cvae+surface: train.weight_surface_distance")
    parser.add_argument("--train-json", type=json.loads, default={}, metavar="JSON",
                        help='keys of the config section train over the default for every family, e.g. \'{"model": {"decoder_hidden": [512, 512]}}\'')
    parser.add_argument("--heldout-ids", nargs="+", default=None, metavar="ID",
                        help="household object ids instead of the household split's first --heldout (to choose a setting elsewhere)")
    parser.add_argument("--modes", nargs="+", default=list(MODES), choices=list(MODES))
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--in-distribution", type=int, default=0, metavar="K",
                        help="also raw samples on K training objects (one per family, first in id order), not turned")
    parser.add_argument("--reuse-models", action="store_true", help="a model file already in OUT is sampled, not trained again")
    parser.add_argument("--skip-heldout", action="store_true", help="no held-out calls (with --in-distribution on reused models)")
    parser.add_argument("--tabulate", action="store_true", help="only pool every OUT/side_by_side_seed*.csv into OUT/side_by_side.md")
    args = parser.parse_args(argv)
    if args.tabulate:
        return tabulate(args.out_dir)
    import torch

    torch.set_num_threads(args.threads)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    grasps, object_ids = training_grasps(args.dataset, args.objects, args.train_objects)
    print(f"training data: {len(grasps)} held grasps on {len(object_ids)} objects", flush=True)
    rows = []
    csv_path = args.out_dir / f"side_by_side_seed{'_'.join(map(str, args.seeds))}{'_training_objects' if args.skip_heldout else ''}.csv"
    for seed in args.seeds:
        meshes = heldout_meshes(args.heldout, seed, args.heldout_ids)
        for family in args.families:
            model = args.out_dir / f"seed_{seed}" / f"{family}.pt"
            model.parent.mkdir(parents=True, exist_ok=True)
            reuse = args.reuse_models and model.is_file()
            train_s = float("nan") if reuse else train_family(family, grasps, object_ids, args.objects, args.steps, seed, model,
                                                                (args.surface_penetration_weight, args.surface_distance_weight),
                                                                args.train_json)
            calls = [] if args.skip_heldout else [(mode, mode, meshes) for mode in args.modes]
            if args.in_distribution:
                calls.append((TRAINING_OBJECTS_MODE, "raw", training_meshes(object_ids, args.in_distribution)))
            for label, mode, chosen in calls:
                folder = args.out_dir / f"seed_{seed}" / f"{family}_{mode.replace(' ', '_') if label == mode else 'raw_training_objects'}"
                for row in evaluate(model, chosen, args.n, seed, mode, folder, args.threads):
                    rows.append({"seed": seed, "family": family, "mode": label, **row, "training_cpu_s": round(train_s, 1)})
                with open(csv_path, "w", newline="") as file:  # rewritten after every call: a stopped run keeps what it measured
                    writer = csv.DictWriter(file, fieldnames=list(rows[0]))
                    writer.writeheader()
                    writer.writerows(rows)
                print("\n".join(summary_table([r for r in rows if r["seed"] == seed])), flush=True)
    print(f"{len(grasps)} held dataset grasps on {len(object_ids)} training objects; {args.steps} steps per family and seed; "
          f"{len(meshes)} held-out objects at seeded yaw, {args.n} grasps each per mode.")
    return tabulate(args.out_dir)


def tabulate(out_dir: Path) -> int:
    """Pool every ``side_by_side_seed*.csv`` of ``out_dir`` (one per call of this script, e.g. seeds run in parallel) into
    ``side_by_side.md``: seeds pooled, then each seed."""
    rows = []
    for path in sorted(out_dir.glob("side_by_side_seed*.csv")):
        with open(path, newline="") as file:
            rows += [{**r, **{k: int(r[k]) for k in ("seed", "attempts", "held", "distinct")},
                      **{k: float(r[k]) for k in ("start_depth_mm_median", "training_cpu_s")}} for r in csv.DictReader(file)]  # fmt: skip
    seeds = sorted({r["seed"] for r in rows})
    report = ["# Generators side by side on the same data", "",
              f"## Seeds {', '.join(map(str, seeds))} pooled", "", *summary_table(rows), ""]  # fmt: skip
    for seed in seeds:
        report += [f"## Seed {seed}", "", *summary_table([r for r in rows if r["seed"] == seed]), ""]
    (out_dir / "side_by_side.md").write_text("\n".join(report))
    print("\n".join(report))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
