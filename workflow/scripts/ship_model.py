"""Ship a finished run's model: a half-precision copy, its evaluator, its card (MODEL_CARD.md) and card.json.

    python workflow/scripts/ship_model.py --run RUN [--seed-runs RUN1 RUN2] \
        --configfile config.yaml config/profiles/household_model.yaml \
        --command "snakemake --cores 2 all --configfile config.yaml config/profiles/household_model.yaml"

Reads from the run: the model (``results/model/cvae.pt``), the learned evaluator that ranked its samples
(``results/evaluator/evaluator.pt`` when the run trained one; the file ``evaluator.source`` names when it reused one:
``shipped``, the evaluator shipped beside the model this one replaces, its facts taken from that model's card), its
config files, the object catalog, the stability table, the grasp shards it trained on (the grasp dataset's,
``results/dataset/``, and its own optimized / curated / lift-validated ones: counts), the evaluation
(``results/eval/metrics.csv``, ``per_object.csv``; held-out rows per split, ``evaluation.subsets``) and
Snakemake's per-job benchmark files (time per stage). ``--seed-runs``: the same profile at other training seeds
(``train.seed``), tabulated beside the shipped one. Writes to ``--out``: ``cvae.pt`` (weights and codes in float16,
loads with ``torch.load(..., weights_only=True)``), ``evaluator.pt``, ``training_grasps.zarr`` (the grasps it was
trained on), ``card.json`` (everything the card says, machine readable; the shipped-model test reads its ``check``
block) and ``MODEL_CARD.md``.

The ``check`` block is the learning ladder on a few objects, measured on the shipped copy
with ``model.shipped_check.shipped_model_check`` (and on the float32 original, for comparison): fit
errors on training objects and raw lift success on held-out objects of both splits. A test repeats it on
freshly rebuilt objects and compares within sampling noise.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import torch
import yaml

from dexlite_pipeline.config import merge_config
from dexlite_pipeline.evaluation.subsets import run_split_rows, split_subsets
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store, write_grasp_store
from dexlite_pipeline.model.checkpoint import save_half_precision_copy
from dexlite_pipeline.dataset.hand import hand_attrs
from dexlite_pipeline.hand.choice import hand_record
from dexlite_pipeline.model.shipped import SHIPPED_MODEL_DIRS
from dexlite_pipeline.model.shipped_check import shipped_model_check
from dexlite_pipeline.settings import build_config

CARD_METHODS = ("cvae_raw", "cvae_post", "random_post", "cvae_recon", "cvae_recon_post", "cvae_prior_train", "cvae_prior_train_post")
# Held-out methods of the card's per-split table, best path first.
SPLIT_METHODS = ("cvae_ranked_post", "cvae_post", "optimization", "random_post", "shipped_post", "cvae_ranked", "cvae_raw", "shipped_raw")


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
    from_dataset = store_rows((run / "results" / "dataset").glob("shard_*.zarr"))
    dataset_held = [s.object_id[np.asarray(s.arrays["lift_success"], bool)] for s in from_dataset if len(s)]
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
        "dataset_grasps": sum(len(s) for s in from_dataset), "dataset_held_grasps": int(sum(len(h) for h in dataset_held)),
        "dataset_objects_with_held_grasps": len(set(np.concatenate(dataset_held).tolist())) if dataset_held else 0,
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
    """The check's objects: the first training objects the model fitted (sorted ids) and the first held-out objects
    of each split the run evaluated (household split, benchmark split), ``heldout_count`` in all."""
    catalog = pd.read_parquet(run / "results" / "objects" / "catalog.parquet")
    train = sorted(checkpoint["train_object_ids"])[:train_count]
    splits = list(split_subsets(catalog).values())
    heldout: list[str] = []
    for k, ids in enumerate(splits):
        share = -(-(heldout_count - len(heldout)) // (len(splits) - k))
        heldout += ids[:share]
    return train, heldout


def split_rows(run: Path, label: str, wall_to_cpu: bool = False) -> list[dict]:
    """The run's held-out rows per split (``evaluation.subsets``), labelled ``label``, as JSON records."""
    return json.loads(run_split_rows(run, SPLIT_METHODS, label, wall_to_cpu).to_json(orient="records"))


def evaluator_facts(run: Path) -> dict | None:
    """What the run's evaluator training recorded (examples, objects, validation AUC), or None without one."""
    path = run / "results" / "evaluator" / "training.json"
    if not path.is_file():
        return None
    facts = json.loads(path.read_text())
    keep = ("examples", "held", "sources", "validation_auc_held", "validation_auc_six_dir", "best_epoch")
    return {**{k: facts.get(k) for k in keep}, "train_objects": len(facts.get("train_object_ids") or [])}


def ranking_evaluator(run: Path, raw_config: dict, hand: str) -> tuple[bytes | None, dict | None]:
    """(the bytes, the card's facts) of the evaluator that ranked the run's samples: the one the run trained
    (``evaluator.source: train``, its ``training.json``), or the one ``evaluator.source`` names (``shipped``: the facts of
    the card shipped beside it, which says which model's samples it learned from). (None, None) without one."""
    from dexlite_pipeline.model.shipped import SHIPPED, TRAINED_BY_THE_RUN, ranking_evaluator_file, shipped_file

    section = raw_config.get("evaluator", {})
    if not section.get("enabled", True):
        return None, None
    source = str(section.get("source", TRAINED_BY_THE_RUN))
    given = ranking_evaluator_file(source, hand, base=run)
    if given is None:
        trained = run / "results" / "evaluator" / "evaluator.pt"
        return (trained.read_bytes(), evaluator_facts(run)) if trained.is_file() else (None, None)
    facts: dict = {} if source == SHIPPED else {"source": f"in {source}"}
    card = shipped_file(hand, "card.json") if source == SHIPPED else None
    if card is not None:
        previous = json.loads(card.read_text())
        facts.update(previous.get("evaluator") or {})  # a reused evaluator's card keeps where it was trained ("source")
        facts.setdefault("source", f"shipped with the model of {previous['date']} and trained on that model's samples (code {previous['code_version']})")
    return given.read_bytes(), facts


def ranking_selection(run: Path, config: dict) -> float | None:
    """How many of the model's samples each simulated ranked grasp was chosen from: the ranking's pool per object
    (``results/sample`` stores' attributes) over the grasps per object the evaluation simulated of the ranked rows
    (``evaluate.grasps_per_object``, at most those kept). None without ranked rows."""
    import zarr

    pool = ranked_objects = 0.0
    kept_per_object = None
    for path in sorted((run / "results" / "sample").glob("shard_*.zarr")):
        ranking = dict(zarr.open_group(str(path), mode="r").attrs).get("ranking") or {}
        if ranking.get("kept"):
            pool += ranking["pool"]
            kept_per_object = ranking["kept_per_object"]
            ranked_objects += ranking["kept"] / kept_per_object
    if not pool or kept_per_object is None:
        return None
    simulated = min(kept_per_object, int(config.get("evaluate", {}).get("grasps_per_object", kept_per_object)))
    return pool / ranked_objects / simulated


def code_type_share(payload: dict) -> dict[str, float]:
    """Grasp type -> share of a checkpoint's stored codes (what ``sample.type_mix: training`` deals an object's samples by)."""
    from dexlite_pipeline.model.type_condition import training_mix

    vocabulary = tuple(payload.get("grasp_types") or ())
    codes_type = payload["state_dict"].get("codes_type")
    if not vocabulary or codes_type is None:
        return {}
    return dict(sorted(zip(vocabulary, map(float, training_mix(codes_type.numpy(), vocabulary))), key=lambda kv: -kv[1]))


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


def _rate(row: dict) -> str:
    return f"{percent(row['held_rate'])} ({percent(row['held_ci95_low'])}–{percent(row['held_ci95_high'])})"


def split_table_lines(rows: list[dict]) -> list[str]:
    """The card's held-out table: per split, method and training seed."""
    lines = []
    for subset in dict.fromkeys(r["subset"] for r in rows):
        objects = next(r["objects"] for r in rows if r["subset"] == subset)
        lines += [f"**{subset}** ({objects} objects, at {'their real size' if subset == 'household split' else '8–12 cm'}):", "",
                  "| method | training seed | attempts | held per attempt | six directions | distinct held / object | CPU-s / distinct held |",
                  "| --- | --- | ---: | --- | ---: | ---: | ---: |"]  # fmt: skip
        for method in SPLIT_METHODS:
            for r in (r for r in rows if r["subset"] == subset and r["method"] == method):
                cost = r["cpu_seconds_per_distinct_held"]  # None (JSON null) where nothing held
                lines.append(f"| {method} | {r['run']} | {r['attempts']} | {_rate(r)} | {percent(r['six_dir_rate'])} | "
                             f"{r['distinct_held_per_object']:.2f} | {'–' if cost is None else f'{cost:.3f}'} |")  # fmt: skip
        lines.append("")
    return lines


def card_markdown(card: dict) -> str:
    counts, training, check = card["data"], card["training"], card["check"]
    dataset = counts.get("dataset_held_grasps", 0) > 0
    hand = card.get("hand") or {"name": "shadow", "joint_names": [None] * 22}
    joints = len(hand["joint_names"])
    folder = str(card["config"].get("dataset", {}).get("root") or "dataset").rstrip("/").split("/")[-1]
    source = (f"lift-validated tabletop grasps of the DexLite grasp dataset (`{folder}/`: generated household objects at their real size, "
              "each standing on its table)" if dataset else "lift-validated grasps of the run's own objects")  # fmt: skip
    hand_words = "the Shadow Hand" if hand["name"] == "shadow" else f"the hand `{hand['name']}`"
    lines = [
        f"# Model card: {card['name']}",
        "",
        f"A PointNet + CVAE grasp generator for {hand_words} ({6 + joints}-D pose: palm translation, palm rotation as XYZ Euler angles,",
        f"{joints} joint angles), trained on {source}, with the learned grasp evaluator that ranks its samples (`evaluator.pt`)."
        if card.get("evaluator") else f"{joints} joint angles), trained on {source}.",
        f"`cvae.pt` stores weights and latent codes in float16 ({card['file_megabytes']:.1f} MB); `load_checkpoint` restores float32."
        + (f" Each training cloud keeps at most {kept['max_codes_per_cloud']} of its training codes ({kept['after']:,} of {kept['before']:,}); "
           + ("the run's held-out results below were measured with the same codes (the run's model is the capped copy)."
              if card.get("run_codes_kept") == kept else "the run's held-out results below were measured with all of them.")
           if (kept := card.get("codes_kept")) else ""),
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
        f"- Objects: {counts['objects_prepared']} of {counts['objects_listed']} prepared, {counts['objects_stable']} table-stable "
        f"({counts['objects_train_stable']} training, {counts['objects_heldout_stable']} held out: never trained on).",
    ]
    if dataset:
        lines.append(f"- From the grasp dataset: {counts['dataset_grasps']} tested grasps of the training objects, **{counts['dataset_held_grasps']} "
                     f"held** on {counts['dataset_objects_with_held_grasps']} objects (the dataset's card, `{folder}/CARD.md`, says how each "
                     "batch made them and its CPU time).")  # fmt: skip
    if counts["optimized_grasps"] and dataset and not counts["curated_grasps"]:
        lines.append(f"- Optimized by the run from scratch on the held-out objects only (the reference it is measured against, never "
                     f"trained on): {counts['optimized_grasps']} grasps, {counts['optimized_grasps_passing_thresholds']} pass the energy thresholds.")
    elif counts["optimized_grasps"]:
        lines.append(f"- Optimized by the run (energy optimization from scratch): {counts['optimized_grasps']}, of which "
                     f"{counts['optimized_grasps_passing_thresholds']} pass the energy thresholds; curated {counts['curated_grasps']}; lift-tested "
                     f"{counts['lift_tested_grasps']}, {counts['lift_successful_grasps']} hold on {counts['objects_with_lift_successes']} objects"
                     + (" (the held-out objects' reference: optimization from scratch, never trained on)." if dataset else "."))  # fmt: skip
    types = training.get("grasp_types") or {}
    lines += [
        f"- Trained on {training['train_grasps']} grasps of {training['train_objects']} objects ({training['validation_grasps']} grasps held for the validation curve)"
        + (f"; grasp types (training grasps): {', '.join(f'{name} {count:,}' for name, count in sorted(types.items(), key=lambda kv: -kv[1]))}: "
           "`dexlite grasp --grasp-type` asks for one; by default (`sample.type_mix: training`) an object's samples are dealt to the types in "
           "the proportions of the stored codes: " + ", ".join(f"{name} {100 * share:.0f}%" for name, share in training["code_type_share"].items()) + "."
           if len(types) > 1 else "."),
        "- The training grasps (pose, object id, scale) are beside the model in `training_grasps.zarr` (the pipeline's grasp-store format) "
        "and inside `cvae.pt` (`training_grasps`); the objects are rebuilt from their ids by the command above (its prepare_objects stage).",
        "",
        "## Training",
        "",
        f"- {training['steps']} optimizer steps, seed {training['seed']}, {training['wall_s'] / 60:.1f} min wall "
        f"({training['cpu_s'] / 60:.1f} CPU-min) on the machine above"
        + ("; every cloud and its grasps turned about the vertical by a random angle each step (`train.rotation_augmentation`)."
           if card["config"].get("train", {}).get("rotation_augmentation") else "."),
    ]
    evaluator = card.get("evaluator")
    if evaluator:
        auc = evaluator.get("validation_auc_held")
        whose = ("the model's own refined and simulated samples" if "source" not in evaluator
                 else "refined and simulated samples of the model shipped before this one")
        if "examples" in evaluator:
            lines.append(f"- Evaluator: {evaluator['examples']} examples ({evaluator['held']} held) on {evaluator['train_objects']} training objects "
                         f"({whose} beside the training grasps); validation ROC AUC for held "
                         f"{auc:.3f} on training objects it did not fit." if auc is not None else "")  # fmt: skip
        if "source" in evaluator:
            lines.append(f"- The evaluator was not trained again for this model (`evaluator.source: {card['config']['evaluator']['source']}`): "
                         f"it is the one {evaluator['source']}; the held-out rows "
                         "below rank this model's samples with it.")
    lines += [
        "",
        "## Held-out objects",
        "",
        "Tabletop, the lift test with the hand starting at most 2 mm inside the object, 16 attempts per object and method"
        + ("; each held-out object turned about the vertical by its own seeded angle (`objects.heldout_yaw`)"
           if card["config"].get("objects", {}).get("heldout_yaw") else ", each object at the orientation it was generated in")
        + "; "
        "intervals Wilson 95% over attempts. `cvae_ranked_post`: the evaluator keeps the best-scored distinct of the "
        "model's samples, which are then post-optimized (what `dexlite grasp` does), each simulated grasp "
        + (f"the best of {card['ranking_selection']:.0f} samples (`dexlite grasp`: of `evaluator.pool_factor`)"
           if card.get("ranking_selection") else "one of the best-scored")
        + "; `cvae_post`: the model's samples, "
        "post-optimized; `optimization`: from scratch; `shipped_post`: the model shipped before this one. CPU-seconds count "
        "sampling, ranking and refinement per attempt (not the simulation), over the distinct held grasps"
        + (" (this run's stages timed wall seconds on shared cores: each stage's are rescaled by its jobs' CPU time over wall time)."
           if card.get("costs_rescaled_from_wall_time") else "."),
        "",
        *split_table_lines(card["splits"]),
        "## Learning ladder (training objects)",
        "",
    ]
    ladder = [row for row in card["metrics"] if row.get("split") == "train"]
    lines += ["| method | rung | grasps | lift | six-direction | fit errors (deg / mm) |", "| --- | --- | ---: | --- | --- | --- |"] if ladder else [
        "Not sampled by this run (`sample.ladder: false`); the check below measures the fit on a few training objects."]
    for row in ladder:
        fit = "" if row.get("fit_rotation_error_deg_median") is None else f"{row['fit_rotation_error_deg_median']:.1f} / {row['fit_translation_error_mm_median']:.1f}"
        lines.append(
            f"| {row['method']} | {row.get('rung') or ''} | {row['n_grasps']} | {percent(row['lift_success_rate'])} "
            f"({percent(row['lift_success_ci95_low'])}–{percent(row['lift_success_ci95_high'])}) | {percent(row.get('six_dir_success_rate'))} | {fit} |"
        )
    shipped_check, original = check["shipped"], check["float32"]
    lines += [
        "",
        "## Check (repeated by `tests/model/test_shipped_model.py`)",
        "",
        f"Fit on {len(shipped_check['fit']['objects'])} training objects ({shipped_check['fit']['grasps']} training grasps): median "
        f"{shipped_check['fit']['rotation_error_deg_median']:.2f}° / {shipped_check['fit']['translation_error_mm_median']:.2f} mm "
        f"(float32 original: {original['fit']['rotation_error_deg_median']:.2f}° / {original['fit']['translation_error_mm_median']:.2f} mm). "
        f"Raw samples on {len(shipped_check['heldout_raw']['objects'])} held-out objects (floating, no post-optimization): "
        f"{shipped_check['heldout_raw']['lift_successes']}/{shipped_check['heldout_raw']['grasps']} hold "
        f"(float32 original: {original['heldout_raw']['lift_successes']}/{original['heldout_raw']['grasps']}).",
        "",
    ]
    times = card["stage_times"]
    if times:
        total_cpu = sum(t["cpu_s"] for t in times.values())
        lines += ["## Where the time goes", "", "Snakemake's per-job benchmark files, summed per rule (jobs of one rule ran two at a time):", "",
                  "| rule | jobs | wall (min) | CPU (min) | share of CPU |", "| --- | ---: | ---: | ---: | ---: |"]  # fmt: skip
        for rule, t in sorted(times.items(), key=lambda item: -item[1]["cpu_s"]):
            lines.append(f"| {rule} | {t['jobs']} | {t['wall_s'] / 60:.1f} | {t['cpu_s'] / 60:.1f} | {100 * t['cpu_s'] / total_cpu:.0f}% |")
        lines.append("")
    if card.get("learning_curve"):
        lines += ["## Learning curve", "", "See `docs/learning_curve.md` (table and plot).", ""]
    lines += [
        "## Limits",
        "",
        "- Trained on generated household shapes (the families of `objects/household.py`) and, where the dataset holds them, "
        "pybullet_data's procedural shapes, standing on a table, under MuJoCo's lift test "
        "at friction 0.6 with a 0.1 kg object; other objects, masses and physics are untested."
        if dataset else "- Measured on the run's objects under MuJoCo's lift test at friction 0.6; other objects and physics are untested.",
        "- One machine; runs are not bit-identical across machines ("
        + ("the training seeds' spread above is the measure of noise)." if len({r["run"] for r in card["splits"]}) > 1
           else "one training seed above; the spread over training seeds and tool seeds is on the project's results page, docs/results.md)."),
        "",
    ]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", required=True, type=Path)
    parser.add_argument("--seed-runs", nargs="*", type=Path, default=[], help="the same profile at other training seeds (train.seed)")
    parser.add_argument("--configfile", nargs="+", default=["config.yaml", "config/profiles/household_model.yaml"])
    parser.add_argument("--out", type=Path, default=None, help="default: the package data folder of the run's hand (model.shipped.SHIPPED_MODEL_DIRS)")
    parser.add_argument("--command", default="snakemake --cores 2 all --configfile config.yaml config/profiles/household_model.yaml")
    parser.add_argument("--wall-log", type=Path, default=None, help="GNU `time -v` output of the run (its wall time)")
    parser.add_argument("--curve", type=Path, default=None, help="learning-curve table (benchmarks/experiments/learning_curve.py) to record")
    parser.add_argument("--check-train-objects", type=int, default=3)
    parser.add_argument("--check-heldout-objects", type=int, default=4)
    parser.add_argument("--check-grasps", type=int, default=16, help="raw samples per held-out object in the check")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--max-codes-per-cloud", type=int, default=0,
                        help="keep at most this many training codes per training cloud in the shipped copy (0: all; a run measured "
                        "with the same cap, model.checkpoint.save_capped_copy, samples like it)")
    parser.add_argument("--code-version", default=None,
                        help="the commit of the code that made the run, when RUN is not a checkout of it (a folder of hard links "
                        "to a run's stages, with its model capped); default: RUN's git HEAD")
    parser.add_argument("--wall-to-cpu", action="store_true",
                        help="runs made before the stages counted CPU seconds: rescale their costs by the jobs' CPU over wall time")
    args = parser.parse_args()

    run = args.run.resolve()
    code_version = args.code_version or git_version(run)
    source = run / "results" / "model" / "cvae.pt"
    checkpoint = torch.load(source, map_location="cpu", weights_only=True)
    raw_config = merged_config(run, args.configfile)
    hand_name = str(raw_config.get("hand", "shadow"))
    if args.out is None:
        if hand_name not in SHIPPED_MODEL_DIRS:
            parser.error(f"hand {hand_name}: no package folder ships its model (SHIPPED_MODEL_DIRS); give --out")
        args.out = Path("src/dexlite_pipeline/data") / SHIPPED_MODEL_DIRS[hand_name]
    evaluator_bytes, evaluator_record = ranking_evaluator(run, raw_config, hand_name)  # read before the folder is replaced
    if args.out.exists():
        shutil.rmtree(args.out)  # the shipped files of another model go (git history keeps them)
    args.out.mkdir(parents=True)
    shipped = save_half_precision_copy(source, args.out / "cvae.pt", max_codes_per_cloud=args.max_codes_per_cloud)
    if evaluator_bytes is not None:
        (args.out / "evaluator.pt").write_bytes(evaluator_bytes)
    training = checkpoint["training_grasps"]
    hand_of_poses = hand_attrs(checkpoint)  # {} for the Shadow Hand, else the hand and its joint names, as a store records them
    write_grasp_store(args.out / "training_grasps.zarr", GraspSet({
        "hand_pose": training["hand_pose"].numpy(), "object_id": np.asarray(training["object_id"], dtype=object), "scale": training["scale"].numpy(),
    }, hand_of_poses), {"description": "the grasps the shipped model was trained on", "code_version": code_version, **hand_of_poses})  # fmt: skip
    config = build_config(raw_config)
    train_ids, heldout_ids = check_objects(run, checkpoint, args.check_train_objects, args.check_heldout_objects)
    objects = [str(run / "results" / "objects")]
    check = {
        name: shipped_model_check(path, objects, train_ids, heldout_ids, config, args.check_grasps, args.threads, seed=0)
        for name, path in (("shipped", shipped), ("float32", source))
    }
    times = stage_times(run)
    wall = wall_seconds(args.wall_log)
    shipped_payload = torch.load(shipped, map_location="cpu", weights_only=True)
    seed_of = {run: checkpoint.get("seed")}
    for other in args.seed_runs:
        seed_of[other.resolve()] = torch.load(other / "results" / "model" / "cvae.pt", map_location="cpu", weights_only=True).get("seed")
    card = {
        "name": args.out.name,
        "hand": {"name": hand_name, "joint_names": list(checkpoint.get("joint_names") or hand_record(hand_name)["joint_names"])},
        "date": datetime.date.today().isoformat(),
        "command": args.command,
        "config_files": args.configfile,
        "config": raw_config,
        "code_version": code_version,
        "machine": machine(),
        "file_megabytes": shipped.stat().st_size / 1e6,
        "codes_kept": shipped_payload.get("codes_kept"),
        "run_codes_kept": checkpoint.get("codes_kept"),  # the run's own model capped before its evaluation (save_capped_copy)
        "wall_time_h": wall / 3600 if wall else None,
        "stage_times": times,
        "data": data_counts(run),
        "training": {
            "seed": checkpoint.get("seed"), "steps": checkpoint.get("steps"), "train_grasps": checkpoint.get("train_grasps"),
            "grasp_types": checkpoint.get("train_grasp_types"), "code_type_share": code_type_share(shipped_payload),
            "validation_grasps": checkpoint.get("validation_grasps"), "train_objects": len(checkpoint.get("train_object_ids") or []),
            "wall_s": times.get("train_cvae", {}).get("wall_s", float("nan")), "cpu_s": times.get("train_cvae", {}).get("cpu_s", float("nan")),
        },  # fmt: skip
        "evaluator": evaluator_record,
        "ranking_selection": ranking_selection(run, raw_config),
        "metrics": metrics_rows(run),
        "splits": [row for path, seed in seed_of.items() for row in split_rows(path, f"{seed} (shipped)" if path == run else str(seed), args.wall_to_cpu)],
        "costs_rescaled_from_wall_time": args.wall_to_cpu,
        "check": {**check, "threads": args.threads, "seed": 0},
        "learning_curve": json.loads(pd.read_csv(args.curve).to_json(orient="records")) if args.curve else None,
    }
    (args.out / "card.json").write_text(json.dumps(card, indent=1, default=float) + "\n")
    (args.out / "MODEL_CARD.md").write_text(card_markdown(card))
    print(f"{shipped} ({card['file_megabytes']:.1f} MB), {args.out / 'MODEL_CARD.md'}")


if __name__ == "__main__":
    main()
