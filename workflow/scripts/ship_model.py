"""Ship a finished large run's model: a half-precision copy, its card (MODEL_CARD.md) and card.json.

    python workflow/scripts/ship_model.py --run RUN --out src/dexlite_pipeline/data/shadow-hand-large \\
        --curve docs/learning_curve.csv --wall-log RUN.time.log

Reads from the run: the model (``results/model/cvae.pt``), its config files, the object catalog,
the stability table, optimized / curated / lift-validated shards (counts), the evaluation
(``results/eval/metrics.csv``, ``per_object.csv``) and Snakemake's per-job benchmark files
(time per stage). Writes to ``--out``: ``cvae.pt`` (weights and codes in float16, loads with
``torch.load(..., weights_only=True)``), ``training_grasps.zarr`` (the grasps it was trained on), ``card.json`` (everything the card says, machine
readable; the shipped-model test reads its ``check`` block) and ``MODEL_CARD.md``.

The ``check`` block is the learning ladder on a few objects, measured on the shipped copy
with ``model.shipped_check.shipped_model_check`` (and on the float32 original, for comparison): fit
errors on training objects and raw lift success on benchmark objects. A test repeats it on
freshly prepared objects and compares within sampling noise.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import re
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import torch
import yaml

from dexlite_pipeline.config import merge_config
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store, write_grasp_store
from dexlite_pipeline.model.checkpoint import save_half_precision_copy
from dexlite_pipeline.model.shipped_check import shipped_model_check
from dexlite_pipeline.settings import build_config

CARD_METHODS = ("cvae_raw", "cvae_post", "random_post", "cvae_recon", "cvae_recon_post", "cvae_prior_train", "cvae_prior_train_post")


def merged_config(run: Path, configfiles: list[str]) -> dict:
    """The run's config: its config files merged in order (Snakemake's --configfile rule)."""
    config: dict = {}
    for name in configfiles:
        config = merge_config(config, yaml.safe_load((run / name).read_text()) or {})
    return config


def machine() -> dict:
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("model name")), platform.processor())
    memory_kb = next(int(line.split()[1]) for line in Path("/proc/meminfo").read_text().splitlines() if line.startswith("MemTotal"))
    return {
        "cpu": cpu, "logical_cpus": os.cpu_count(), "memory_gb": round(memory_kb / 1024**2, 1), "gpu": torch.cuda.is_available(),
        "python": platform.python_version(), "torch": torch.__version__,
    }  # fmt: skip


def stage_times(run: Path) -> dict:
    """Wall and CPU seconds per rule, summed over its jobs (Snakemake's benchmark files)."""
    times: dict[str, dict[str, float]] = {}
    for path in sorted((run / "logs" / "benchmarks").glob("*.tsv")):
        rule = re.sub(r"_\d{3}$", "", path.stem)
        row = pd.read_csv(path, sep="\t").iloc[0]
        entry = times.setdefault(rule, {"jobs": 0, "wall_s": 0.0, "cpu_s": 0.0})
        entry["jobs"] += 1
        entry["wall_s"] += float(row["s"])
        entry["cpu_s"] += float(row["cpu_time"])
    return times


def store_rows(paths) -> list:
    return [read_grasp_store(p) for p in sorted(paths)]


def data_counts(run: Path) -> dict:
    catalog = pd.read_parquet(run / "results" / "objects" / "catalog.parquet")
    stability = pd.read_parquet(run / "results" / "stability" / "stability.parquet")
    ok = catalog[catalog.status == "ok"]
    stable = set(stability.loc[stability.stable, "object_id"])
    optimized = store_rows((run / "results" / "optimized").glob("shard_*.zarr"))
    curated = store_rows((run / "results" / "curate").glob("shard_*.zarr"))
    lift = store_rows((run / "results" / "lift").glob("shard_*.zarr"))
    lifted = [np.asarray(s.arrays["lift_success"], bool) for s in lift if len(s)]
    lift_ids = [s.object_id[np.asarray(s.arrays["lift_success"], bool)] for s in lift if len(s)]
    return {
        "objects_listed": len(catalog), "objects_prepared": len(ok), "objects_stable": len(stable & set(ok.object_id)),
        "objects_train_stable": len(stable & set(ok.object_id[ok.split == "train"])),
        "objects_heldout_stable": len(stable & set(ok.object_id[ok.split == "heldout"])),
        "optimized_grasps": sum(len(s) for s in optimized),
        "optimized_grasps_passing_thresholds": int(sum(np.asarray(s.arrays["passes_energy_thresholds"], bool).sum() for s in optimized if len(s))),
        "curated_grasps": sum(len(s) for s in curated),
        "lift_tested_grasps": sum(len(s) for s in lift), "lift_successful_grasps": int(sum(x.sum() for x in lifted)),
        "objects_with_lift_successes": len(set(np.concatenate(lift_ids).tolist())) if lift_ids else 0,
    }  # fmt: skip


def metrics_rows(run: Path) -> list[dict]:
    metrics = pd.read_csv(run / "results" / "eval" / "metrics.csv")
    keep = [
        "method", "split", "rung", "n_grasps", "n_objects", "lift_success_rate", "lift_success_ci95_low", "lift_success_ci95_high",
        "lift_success_boot_ci95_low", "lift_success_boot_ci95_high", "six_dir_success_rate", "six_dir_success_ci95_low",
        "six_dir_success_ci95_high", "writeup_protocol_lift_success_rate", "seconds_per_grasp", "fit_rotation_error_deg_median",
        "fit_translation_error_mm_median", "fit_joint_error_rad_mean",
    ]  # fmt: skip
    rows = metrics[metrics.method.isin(CARD_METHODS)][[c for c in keep if c in metrics.columns]]
    return json.loads(rows.to_json(orient="records"))


def check_objects(run: Path, checkpoint: dict, train_count: int, heldout_count: int) -> tuple[list[str], list[str]]:
    """The check's objects: the first training objects the model fitted (sorted ids) and the first benchmark objects."""
    from dexlite_pipeline.objects.sources import benchmark_object_list

    catalog = pd.read_parquet(run / "results" / "objects" / "catalog.parquet")
    prepared = set(catalog.loc[catalog.status == "ok", "object_id"])
    train = sorted(o for o in checkpoint["train_object_ids"] if o.startswith("pb-random-"))[:train_count]
    heldout = [o for o in benchmark_object_list() if o in prepared][:heldout_count]
    return train, heldout


def per_object_rates(run: Path, object_ids: list[str]) -> dict:
    table = pd.read_csv(run / "results" / "eval" / "per_object.csv")
    table = table[table.object_id.isin(object_ids) & table.method.isin(["cvae_raw", "cvae_post", "random_post"])]
    return {f"{r.method}:{r.object_id}": {"n_grasps": int(r.n_grasps), "lift_success_rate": float(r.lift_success_rate)} for r in table.itertuples()}


def git_version(run: Path) -> str:
    commit = subprocess.run(["git", "-C", str(run), "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", str(run), "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True).stdout.strip()
    return commit + ("+local-changes" if dirty else "")


def wall_seconds(log: Path | None) -> float | None:
    """Elapsed wall time from a GNU time -v log of the run, if given."""
    if log is None or not log.exists():
        return None
    match = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (?:(\d+):)?(\d+):([\d.]+)", log.read_text())
    if not match:
        return None
    hours, minutes, seconds = match.groups()
    return int(hours or 0) * 3600 + int(minutes) * 60 + float(seconds)


def percent(value) -> str:
    return "–" if value is None or (isinstance(value, float) and np.isnan(value)) else f"{100 * float(value):.1f}%"


def throughput_lines(card: dict) -> list[str]:
    """Objects and grasps per hour of each data stage (wall clock of its jobs / CPU time)."""
    times, counts = card["stage_times"], card["data"]
    out = []

    def rate(count, rule, key):
        seconds = times.get(rule, {}).get(key, 0.0)
        return count / seconds * 3600 if seconds else float("nan")

    out.append(f"{rate(counts['objects_listed'], 'prepare_objects', 'wall_s'):.0f} objects prepared per hour")
    out.append(f"{rate(counts['optimized_grasps'], 'optimize_grasps', 'cpu_s'):.0f} optimized grasps per CPU-hour")
    out.append(f"{rate(counts['lift_tested_grasps'], 'lift_validate', 'cpu_s'):.0f} grasps lift-tested per CPU-hour")
    cpu_hours = sum(times.get(r, {}).get("cpu_s", 0.0) for r in ("prepare_objects", "stability_filter", "optimize_grasps", "curate", "lift_validate")) / 3600
    if cpu_hours:
        out.append(f"{counts['lift_successful_grasps'] / cpu_hours:.0f} lift-validated grasps per CPU-hour of the whole data pipeline")
    return out


def card_markdown(card: dict) -> str:
    counts, training, check = card["data"], card["training"], card["check"]
    lines = [
        f"# Model card: {card['name']}",
        "",
        "A PointNet + CVAE grasp generator for the Shadow Hand (28-D pose: palm translation, palm rotation as XYZ Euler angles,",
        "22 joint angles), trained by DexLite's large profile on lift-validated grasps of pybullet_data's embedded objects.",
        f"`cvae.pt` stores weights and latent codes in float16 ({card['file_megabytes']:.1f} MB); `load_checkpoint` restores float32.",
        "It loads with `torch.load(path, weights_only=True)` (no pickled code).",
        "",
        "## How it was made",
        "",
        f"- Command: `{card['command']}`",
        f"- Code version: `{card['code_version']}`; config: the merged files {', '.join(card['config_files'])} (in `card.json`, key `config`).",
        f"- Machine: {card['machine']['cpu']}, {card['machine']['logical_cpus']} logical CPUs, {card['machine']['memory_gb']} GB, "
        f"GPU: {'yes' if card['machine']['gpu'] else 'no'}; Python {card['machine']['python']}, torch {card['machine']['torch']}.",
        f"- Date: {card['date']}. Whole run wall time: {card['wall_time_h']:.2f} h." if card.get("wall_time_h") else f"- Date: {card['date']}.",
        "",
        "## Data",
        "",
        f"- Objects: {counts['objects_prepared']} of {counts['objects_listed']} embedded objects prepared, {counts['objects_stable']} table-stable "
        f"({counts['objects_train_stable']} training, {counts['objects_heldout_stable']} held out: the benchmark split).",
        f"- Optimized grasps (energy optimization from scratch): {counts['optimized_grasps']}, of which {counts['optimized_grasps_passing_thresholds']} pass the energy thresholds; "
        f"curated {counts['curated_grasps']}; lift-tested {counts['lift_tested_grasps']}, **{counts['lift_successful_grasps']} hold** "
        f"on {counts['objects_with_lift_successes']} objects.",
        f"- Trained on {training['train_grasps']} grasps of {training['train_objects']} objects ({training['validation_grasps']} grasps held for the validation curve).",
        "- The training grasps (pose, object id, scale) are beside the model in `training_grasps.zarr` (the pipeline's grasp-store format) "
        "and inside `cvae.pt` (`training_grasps`); the objects are pybullet_data's, rebuilt by the command above (its prepare_objects stage).",
        "",
        "## Training",
        "",
        f"- {training['steps']} optimizer steps, seed {training['seed']}, {training['wall_s'] / 60:.1f} min wall "
        f"({training['cpu_s'] / 60:.1f} CPU-min) on the machine above.",
        "",
        "## Learning ladder and benchmark (the run's evaluation)",
        "",
        "Fit and in-distribution rows are measured on training objects, held-out rows on the 48-object benchmark split "
        "(`src/dexlite_pipeline/objects/benchmark_split.yaml`) that no profile trains on; intervals are Wilson 95%.",
        "",
        "| method | rung | grasps | lift | six-direction | fit errors (deg / mm) |",
        "| --- | --- | ---: | --- | --- | --- |",
    ]
    for row in card["metrics"]:
        fit = "" if row.get("fit_rotation_error_deg_median") is None else f"{row['fit_rotation_error_deg_median']:.1f} / {row['fit_translation_error_mm_median']:.1f}"
        lines.append(
            f"| {row['method']} | {row.get('rung') or ''} | {row['n_grasps']} | {percent(row['lift_success_rate'])} "
            f"({percent(row['lift_success_ci95_low'])}–{percent(row['lift_success_ci95_high'])}) | {percent(row.get('six_dir_success_rate'))} | {fit} |"
        )
    lines += [
        "",
        "## Check (repeated by `tests/model/test_shipped_model.py`)",
        "",
        f"Fit on {len(check['shipped']['fit']['objects'])} training objects ({check['shipped']['fit']['grasps']} training grasps): median "
        f"{check['shipped']['fit']['rotation_error_deg_median']:.2f}° / {check['shipped']['fit']['translation_error_mm_median']:.2f} mm "
        f"(float32 original: {check['float32']['fit']['rotation_error_deg_median']:.2f}° / {check['float32']['fit']['translation_error_mm_median']:.2f} mm). "
        f"Raw samples on {len(check['shipped']['heldout_raw']['objects'])} benchmark objects: "
        f"{check['shipped']['heldout_raw']['lift_successes']}/{check['shipped']['heldout_raw']['grasps']} hold "
        f"(float32 original: {check['float32']['heldout_raw']['lift_successes']}/{check['float32']['heldout_raw']['grasps']}).",
        "",
    ]
    times = card["stage_times"]
    if times:
        total_cpu = sum(t["cpu_s"] for t in times.values())
        lines += ["## Where the time goes", "", "Snakemake's per-job benchmark files, summed per rule (jobs of one rule ran two at a time):", "",
                  "| rule | jobs | wall (min) | CPU (min) | share of CPU |", "| --- | ---: | ---: | ---: | ---: |"]  # fmt: skip
        for rule, t in sorted(times.items(), key=lambda item: -item[1]["cpu_s"]):
            lines.append(f"| {rule} | {t['jobs']} | {t['wall_s'] / 60:.1f} | {t['cpu_s'] / 60:.1f} | {100 * t['cpu_s'] / total_cpu:.0f}% |")
        lines += ["", "Throughput: " + "; ".join(throughput_lines(card)) + ".", ""]
    if card.get("learning_curve"):
        lines += ["## Learning curve", "", "See `docs/learning_curve.md` (table and plot).", ""]
    lines += [
        "## Limits",
        "",
        "- Measured on pybullet_data's procedural objects at 8–12 cm scale, with MuJoCo's lift test at friction 0.6; other objects and physics are untested.",
        "- Numbers are from one training seed on one machine; runs are not bit-identical across machines.",
        "",
    ]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", required=True, type=Path)
    parser.add_argument("--configfile", nargs="+", default=["config.yaml", "config/profiles/large.yaml"])
    parser.add_argument("--out", type=Path, default=Path("src/dexlite_pipeline/data/shadow-hand-large"))
    parser.add_argument("--command", default="snakemake --cores 2 all --configfile config/profiles/large.yaml")
    parser.add_argument("--wall-log", type=Path, default=None, help="GNU `time -v` output of the run (its wall time)")
    parser.add_argument("--curve", type=Path, default=None, help="learning-curve table (benchmarks/experiments/learning_curve.py) to record")
    parser.add_argument("--check-train-objects", type=int, default=3)
    parser.add_argument("--check-heldout-objects", type=int, default=4)
    parser.add_argument("--check-grasps", type=int, default=16, help="raw samples per benchmark object in the check")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()

    run = args.run.resolve()
    source = run / "results" / "model" / "cvae.pt"
    checkpoint = torch.load(source, map_location="cpu", weights_only=True)
    args.out.mkdir(parents=True, exist_ok=True)
    shipped = save_half_precision_copy(source, args.out / "cvae.pt")
    training = checkpoint["training_grasps"]
    write_grasp_store(args.out / "training_grasps.zarr", GraspSet({
        "hand_pose": training["hand_pose"].numpy(), "object_id": np.asarray(training["object_id"], dtype=object), "scale": training["scale"].numpy(),
    }), {"description": "the grasps the shipped model was trained on (lift-validated optimized grasps of the large run)", "code_version": git_version(run)})  # fmt: skip
    raw_config = merged_config(run, args.configfile)
    config = build_config(raw_config)
    train_ids, heldout_ids = check_objects(run, checkpoint, args.check_train_objects, args.check_heldout_objects)
    objects = [str(run / "results" / "objects")]
    check = {
        name: shipped_model_check(path, objects, train_ids, heldout_ids, config, args.check_grasps, args.threads, seed=0)
        for name, path in (("shipped", shipped), ("float32", source))
    }
    times = stage_times(run)
    wall = wall_seconds(args.wall_log)
    card = {
        "name": args.out.name,
        "date": datetime.date.today().isoformat(),
        "command": args.command,
        "config_files": args.configfile,
        "config": raw_config,
        "code_version": git_version(run),
        "machine": machine(),
        "file_megabytes": shipped.stat().st_size / 1e6,
        "wall_time_h": wall / 3600 if wall else None,
        "stage_times": times,
        "data": data_counts(run),
        "training": {
            "seed": checkpoint.get("seed"), "steps": checkpoint.get("steps"), "train_grasps": checkpoint.get("train_grasps"),
            "validation_grasps": checkpoint.get("validation_grasps"), "train_objects": len(checkpoint.get("train_object_ids") or []),
            "wall_s": times.get("train_cvae", {}).get("wall_s", float("nan")), "cpu_s": times.get("train_cvae", {}).get("cpu_s", float("nan")),
        },  # fmt: skip
        "metrics": metrics_rows(run),
        "benchmark_per_object": per_object_rates(run, heldout_ids),
        "check": {**check, "threads": args.threads, "seed": 0},
        "learning_curve": json.loads(pd.read_csv(args.curve).to_json(orient="records")) if args.curve else None,
    }
    (args.out / "card.json").write_text(json.dumps(card, indent=1, default=float) + "\n")
    (args.out / "MODEL_CARD.md").write_text(card_markdown(card))
    print(f"{shipped} ({card['file_megabytes']:.1f} MB), {args.out / 'MODEL_CARD.md'}")


if __name__ == "__main__":
    main()
