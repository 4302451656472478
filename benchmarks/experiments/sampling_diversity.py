"""Success and diversity of the shipped model's sample + post-optimization path, per sampling setting, beside
optimization from scratch on the same objects with the same number of attempts.

    python benchmarks/experiments/sampling_diversity.py --objects 12 --attempts 16 --seeds 0 1 [--settings NAME ...]
        [--objects-dir DIR] [--model PATH] [--threads 1] [--csv OUT.csv]
    python benchmarks/experiments/sampling_diversity.py --tabulate OUT.csv [MORE.csv ...]

Objects: ``--objects`` of the benchmark split (the first ones, or after ``--skip-objects``) (``objects/benchmark_split.yaml``, never trained
on), prepared with the checkout's ``objects`` settings into ``--objects-dir`` (reused when already there).
Each setting samples ``--attempts`` grasps per object (scales dealt in turn from ``sample.scales``) with
the shipped model, post-optimizes them (``post_optimize``, 200 steps, close-start schedule) and runs the
lift and six-direction tests (``lift``). Baselines with the same attempts: ``random_post`` (convex-hull
starts, the same 200-step budget, exploring schedule) and ``optimization`` (``optimize_grasps``: 2,000 steps, counted
per attempt, no energy filter). The setting ``config`` uses config.yaml's ``sample`` section as it is; the
other named settings are ``SETTING_BASE`` (the sampling defaults before 2026-12-02) with their own options.

Per setting and seed: held per attempt (lift; six-direction among all attempts), distinct held grasps per
object (``evaluation.diversity``: config ``diversity``, per object and scale, summed per object), joint
entropy of the held grasps (``evaluation.metrics.joint_entropy_bits``, mean over joints, pooled over the
objects) and CPU-seconds (this process: sampling, optimization and tests) per held and per distinct held
grasp. The table gives the mean over seeds and the range (min-max) in brackets.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import logging
import math
import platform
import time
from pathlib import Path

import numpy as np

# every named setting is these sampling options with its own on top (independent of config.yaml); "config" is
# config.yaml's sample section as it is
SETTING_BASE = {
    "latent_prior": "neighbours", "neighbour_clouds": 1, "latent_temperature": 1.0, "anchor_rule": "matched", "anchor_region_m": 0.02,
    "debias_training": False, "match_candidates": 1, "debias_codes": False,
}  # fmt: skip
SETTINGS: dict[str, dict] = {
    "config": {},
    "neighbours1_matched": {"latent_prior": "neighbours", "neighbour_clouds": 1, "anchor_rule": "matched"},
    "neighbours8_matched": {"latent_prior": "neighbours", "neighbour_clouds": 8, "anchor_rule": "matched"},
    "neighbours32_matched": {"latent_prior": "neighbours", "neighbour_clouds": 32, "anchor_rule": "matched"},
    "neighbours4_matched": {"latent_prior": "neighbours", "neighbour_clouds": 4, "anchor_rule": "matched"},
    "neighbours16_matched": {"latent_prior": "neighbours", "neighbour_clouds": 16, "anchor_rule": "matched"},
    "neighbours8_matched_c8": {"latent_prior": "neighbours", "neighbour_clouds": 8, "anchor_rule": "matched", "match_candidates": 8},
    "neighbours8_matched_c32": {"latent_prior": "neighbours", "neighbour_clouds": 8, "anchor_rule": "matched", "match_candidates": 32},
    "neighbours16_matched_c8": {"latent_prior": "neighbours", "neighbour_clouds": 16, "anchor_rule": "matched", "match_candidates": 8},
    "neighbours8_matched_codes": {"latent_prior": "neighbours", "neighbour_clouds": 8, "anchor_rule": "matched", "debias_codes": True},
    "neighbours4_matched_codes": {"latent_prior": "neighbours", "neighbour_clouds": 4, "anchor_rule": "matched", "debias_codes": True},
    "neighbours16_matched_codes": {"latent_prior": "neighbours", "neighbour_clouds": 16, "anchor_rule": "matched", "debias_codes": True},
    "neighbours8_matched_codes_T2": {
        "latent_prior": "neighbours", "neighbour_clouds": 8, "anchor_rule": "matched", "debias_codes": True, "latent_temperature": 2.0,
    },
    "neighbours8_matched_T2": {"latent_prior": "neighbours", "neighbour_clouds": 8, "anchor_rule": "matched", "latent_temperature": 2.0},
    "neighbours8_matched_codes_T4": {
        "latent_prior": "neighbours", "neighbour_clouds": 8, "anchor_rule": "matched", "debias_codes": True, "latent_temperature": 4.0,
    },
    "aggregate_matched": {"latent_prior": "aggregate", "anchor_rule": "matched"},
    "aggregate_matched_T3": {"latent_prior": "aggregate", "latent_temperature": 3.0, "anchor_rule": "matched"},
    "aggregate_debiased": {"latent_prior": "aggregate", "anchor_rule": "debiased"},
    "aggregate_spread": {"latent_prior": "aggregate", "anchor_rule": "spread"},
    "neighbours8_debiased": {"latent_prior": "neighbours", "neighbour_clouds": 8, "anchor_rule": "debiased"},
    "standard_T1_uniform": {"latent_prior": "standard", "latent_temperature": 1.0, "anchor_rule": "uniform"},
    "standard_T1_debiased": {"latent_prior": "standard", "latent_temperature": 1.0, "anchor_rule": "debiased"},
    "standard_T1_spread": {"latent_prior": "standard", "latent_temperature": 1.0, "anchor_rule": "spread"},
    "standard_T0.5_debiased": {"latent_prior": "standard", "latent_temperature": 0.5, "anchor_rule": "debiased"},
    "standard_T2_debiased": {"latent_prior": "standard", "latent_temperature": 2.0, "anchor_rule": "debiased"},
    "standard_T1_debiased_training": {"latent_prior": "standard", "latent_temperature": 1.0, "anchor_rule": "debiased", "debias_training": True},
}
BASELINES = ("random_post", "optimization")
COLUMNS = (
    "setting", "seed", "objects", "attempts", "held", "six_dir_held", "held_rate", "six_dir_rate", "distinct_held", "distinct_per_object",
    "distinct_per_object_min", "joint_entropy_bits", "cpu_seconds", "cpu_s_per_held", "cpu_s_per_distinct", "distinct_by_object",
)  # fmt: skip

log = logging.getLogger("sampling_diversity")


def prepare(objects_dir: Path, count: int, config: dict, threads: int, skip: int = 0) -> list:
    """``count`` benchmark objects after the first ``skip``, prepared into ``objects_dir`` unless they are there already."""
    from dexlite_pipeline.config import from_section
    from dexlite_pipeline.objects.assets import available_object_ids, load_asset
    from dexlite_pipeline.objects.prepare import ObjectsConfig, prepare_objects
    from dexlite_pipeline.objects.sources import benchmark_object_list, pybullet_random_source_of

    ids = list(benchmark_object_list())[skip : skip + count]
    missing = [oid for oid in ids if oid not in available_object_ids([str(objects_dir)])]
    if missing:
        objects = from_section(ObjectsConfig, config.get("objects"), "config.objects")
        catalog = prepare_objects([pybullet_random_source_of(oid) for oid in ids], objects_dir, objects, int(config.get("seed", 0)), threads)
        bad = catalog[catalog["status"] != "ok"]
        if len(bad):
            log.warning("objects not prepared: %s", dict(zip(bad["object_id"], bad["reason"])))
    return [load_asset([str(objects_dir)], oid) for oid in ids if oid in available_object_ids([str(objects_dir)])]


def synthesized_starts(model_path: str, assets, object_index, scale, sample, generator):
    """CVAE samples (B, 28) with the sample settings ``sample`` (a SampleConfig)."""
    from dexlite_pipeline.model.checkpoint import cloud_reading, load_checkpoint
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.sampling import synthesize

    model, checkpoint = load_checkpoint(model_path, "cpu")
    points, fixed = cloud_reading(checkpoint, sample.points_per_cloud)
    return synthesize(
        model, ObjectClouds(assets), object_index, scale, points, generator, sample.latent_prior, sample.latent_temperature, fixed,
        sample.anchor_rule, sample.neighbour_clouds, sample.anchor_region_m, sample.debias_training, sample.match_candidates,
        sample.debias_codes, sample.yaw_candidates,
    )


def run_setting(name: str, assets, attempts: int, seed: int, config: dict, model_path: str, objects_dir: Path, threads: int) -> dict:
    """One row of measurements: ``name`` is a key of SETTINGS or a baseline."""
    import torch

    from dexlite_pipeline.config import from_section
    from dexlite_pipeline.energy.grasp_energy import EnergyConfig, GraspEnergy
    from dexlite_pipeline.evaluation.diversity import DiversityConfig, distinct_grasp_labels
    from dexlite_pipeline.evaluation.metrics import joint_entropy_bits
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.optim.config import PostOptimizeConfig
    from dexlite_pipeline.optim.post import refine
    from dexlite_pipeline.model.sampling import SampleConfig
    from dexlite_pipeline.optim.init import HullSampler, initial_poses
    from dexlite_pipeline.sim.config import lift_config_from
    from dexlite_pipeline.sim.results import lift_grasp_set
    from dexlite_pipeline.tools.grasp import synthesize_from_scratch

    sample = from_section(SampleConfig, config.get("sample"), "config.sample")
    post = from_section(PostOptimizeConfig, config.get("post_optimize"), "config.post_optimize")
    margin = from_section(EnergyConfig, config.get("energy"), "config.energy").self_penetration_margin_m
    diversity = from_section(DiversityConfig, config.get("diversity"), "config.diversity")
    ids = [a.object_id for a in assets]
    object_index = np.repeat(np.arange(len(assets)), attempts)
    scale = np.tile(np.resize(np.asarray(sample.scales, np.float32), attempts), len(assets))
    generator = torch.Generator().manual_seed(seed)
    hand = ShadowHand()
    started = time.process_time()
    if name == "optimization":
        grasps = synthesize_from_scratch(assets, {oid: tuple(sample.scales) for oid in ids}, attempts, config, "cpu", seed)
        pose, scale, grasp_ids = grasps.hand_pose, grasps.scale.astype(np.float32), grasps.object_id
    else:
        energy = GraspEnergy.from_assets(
            hand, assets, EnergyConfig(weights=post.energy_weights, object_point_spacing_m=post.energy_point_spacing_m, self_penetration_margin_m=margin)
        )
        obj, sc = torch.as_tensor(object_index), torch.as_tensor(scale)
        if name == "random_post":
            starts, contacts = initial_poses(hand, HullSampler(assets), obj, sc, post.random_init, generator), "random"
        else:
            options = {**SETTING_BASE, **SETTINGS[name]} if name != "config" else {}
            starts = synthesized_starts(model_path, assets, object_index, scale, dataclasses.replace(sample, **options), generator)
            contacts = "surface"
        pose = refine(energy, starts, obj, sc, post, generator, contacts).arrays["hand_pose"]
        grasp_ids = np.asarray([ids[i] for i in object_index], dtype=object)
    grasps = GraspSet({"hand_pose": np.asarray(pose, np.float32), "object_id": np.asarray(grasp_ids, dtype=object), "scale": scale})
    tested, _ = lift_grasp_set(grasps, [str(objects_dir)], lift_config_from(config, six_directions=True), threads)
    cpu = time.process_time() - started
    held = np.asarray(tested.arrays["lift_success"], bool)
    six = np.asarray(tested.arrays["six_dir_success"], bool) & held
    groups = np.asarray([f"{o}|{s:.4f}" for o, s in zip(tested.object_id, tested.scale)])
    labels = distinct_grasp_labels(tested.hand_pose[held], groups[held], diversity.distinct_translation_m, diversity.distinct_rotation_deg)
    distinct = {oid: len(set(labels[tested.object_id[held] == oid].tolist())) for oid in ids}
    limits = hand.joint_limits.cpu().numpy()
    entropy = float(np.mean(joint_entropy_bits(tested.hand_pose[held, 6:], limits))) if held.any() else math.nan
    total_distinct = sum(distinct.values())
    return {
        "setting": name, "seed": seed, "objects": len(ids), "attempts": len(tested), "held": int(held.sum()), "six_dir_held": int(six.sum()),
        "held_rate": held.mean(), "six_dir_rate": six.mean(), "distinct_held": total_distinct, "distinct_per_object": total_distinct / len(ids),
        "distinct_per_object_min": min(distinct.values()), "joint_entropy_bits": entropy, "cpu_seconds": cpu,
        "cpu_s_per_held": cpu / held.sum() if held.any() else math.inf, "cpu_s_per_distinct": cpu / total_distinct if total_distinct else math.inf,
        "distinct_by_object": json.dumps(distinct),
    }  # fmt: skip


def _cell(values: list[float], fmt: str) -> str:
    """Mean and [min-max] of one column over seeds."""
    values = [float(v) for v in values]
    text = format(float(np.mean(values)), fmt)
    return text if len(values) == 1 else f"{text} [{format(min(values), fmt)}–{format(max(values), fmt)}]"


def table(rows: list[dict], reference: str = "optimization") -> str:
    """Markdown table: one line per setting, seeds pooled (mean [min–max]); distinct grasps and entropy also as a share of
    the ``reference`` setting's means (optimization from scratch by default)."""
    names = list(dict.fromkeys(r["setting"] for r in rows))
    by = {n: [r for r in rows if r["setting"] == n] for n in names}
    ref = by.get(reference, [])
    ref_distinct = np.mean([float(r["distinct_per_object"]) for r in ref]) if ref else math.nan
    ref_entropy = np.mean([float(r["joint_entropy_bits"]) for r in ref]) if ref else math.nan
    lines = [
        "| setting | seeds | attempts | held per attempt (lift) | six-direction | distinct held / object | (min object) | "
        f"vs {reference} | joint entropy (bits) | vs {reference} | CPU s / held | CPU s / distinct |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for name in names:
        group = by[name]
        col = lambda key: [float(r[key]) for r in group]  # noqa: E731
        lines.append(
            f"| {name} | {len(group)} | {int(np.mean(col('attempts')))} | {_cell([100 * v for v in col('held_rate')], '.1f')}% | "
            f"{_cell([100 * v for v in col('six_dir_rate')], '.1f')}% | {_cell(col('distinct_per_object'), '.2f')} | "
            f"{_cell(col('distinct_per_object_min'), '.0f')} | {100 * np.mean(col('distinct_per_object')) / ref_distinct:.0f}% | "
            f"{_cell(col('joint_entropy_bits'), '.2f')} | {100 * np.mean(col('joint_entropy_bits')) / ref_entropy:.0f}% | "
            f"{_cell(col('cpu_s_per_held'), '.2f')} | {_cell(col('cpu_s_per_distinct'), '.2f')} |"
        )
    return "\n".join(lines)


def read_rows(paths: list[str]) -> list[dict]:
    """The CSVs' rows, one per (setting, seed, objects, attempts): a repeated measurement (identical, the runs are
    deterministic) counts once, the last one read."""
    rows: dict[tuple, dict] = {}
    for path in paths:
        with open(path, newline="") as handle:
            for row in csv.DictReader(handle):
                rows[(row["setting"], row["seed"], row["objects"], row["attempts"])] = row
    return list(rows.values())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", type=int, default=12, help="N objects of the benchmark split (after --skip-objects)")
    parser.add_argument("--skip-objects", type=int, default=0, help="start after this many benchmark objects")
    parser.add_argument("--attempts", type=int, default=16, help="grasps per object and setting")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="sampling seeds")
    parser.add_argument("--settings", nargs="+", default=[*SETTINGS, *BASELINES], help=f"of {', '.join([*SETTINGS, *BASELINES])}")
    parser.add_argument("--objects-dir", default="benchmark_objects", help="prepared objects (made when missing)")
    parser.add_argument("--model", default=None, help="model file (default: the shipped model)")
    parser.add_argument("--threads", type=int, default=1, help="lift-test threads and object preparation workers")
    parser.add_argument("--csv", default=None, help="append the rows to this CSV")
    parser.add_argument("--tabulate", nargs="+", default=None, help="only print the table of these CSVs")
    parser.add_argument("--reference", default="optimization", help="setting the ratio columns divide by")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(name)s %(message)s")
    if args.tabulate:
        print(table(read_rows(args.tabulate), args.reference))
        return
    import torch

    from dexlite_pipeline.model.shipped import model_or_shipped
    from dexlite_pipeline.config import default_config

    torch.set_num_threads(1)
    unknown = [s for s in args.settings if s not in SETTINGS and s not in BASELINES]
    if unknown:
        parser.error(f"unknown settings {unknown}")
    config = default_config()
    model_path = str(model_or_shipped(args.model))
    objects_dir = Path(args.objects_dir)
    assets = prepare(objects_dir, args.objects, config, args.threads, args.skip_objects)
    print(f"# {platform.node()} {platform.processor() or platform.machine()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
          f"{len(assets)} benchmark objects x {args.attempts} attempts, model {model_path}, lift threads {args.threads}", flush=True)
    rows = []
    for seed in args.seeds:
        for name in args.settings:
            row = run_setting(name, assets, args.attempts, seed, config, model_path, objects_dir, args.threads)
            rows.append(row)
            print(f"{name} seed {seed}: held {row['held']}/{row['attempts']}, six {row['six_dir_held']}, distinct/object "
                  f"{row['distinct_per_object']:.2f}, entropy {row['joint_entropy_bits']:.2f}, cpu {row['cpu_seconds']:.0f}s", flush=True)
            if args.csv:
                path = Path(args.csv)
                new = not path.exists()
                with path.open("a", newline="") as handle:
                    writer = csv.DictWriter(handle, fieldnames=COLUMNS)
                    if new:
                        writer.writeheader()
                    writer.writerow(row)
    print(table(rows, args.reference))


if __name__ == "__main__":
    main()
