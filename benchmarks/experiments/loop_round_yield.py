"""What one data-loop round keeps, per sampling setting: one round redone beside a finished run.

    python benchmarks/experiments/loop_round_yield.py RUN_DIR OUT_DIR --variant NAME[:KEY=VALUE,...] [--variant ...]
        [--configfile FILE ...] [--round 1]

``RUN_DIR`` is a finished workflow folder (``config.yaml``, ``results/`` with the round's previous model and grasp
set: for round 1 ``results/model/cvae.pt`` and round 0's set, which is made here from ``results/lift/`` by
``dexlite loop-initial-set`` when the run had no loop, so a run up to ``train_cvae`` is enough). Its config is ``RUN_DIR/config.yaml`` overlaid by each ``--configfile`` (as given to snakemake) and then
by the variant's settings (dotted keys, YAML values: ``--variant matched16:loop.anchor_rule=matched,loop.match_candidates=16``).
Per variant the round's training part runs with the stages' own commands (``dexlite loop-sample``,
``loop-post-optimize``, ``loop-validate`` per shard, then ``loop-merge``) into ``OUT_DIR/<variant>/``; nothing in
``RUN_DIR`` is written. Prints, and writes to ``OUT_DIR/loop_round_yield.csv``: samples, drops per reason, grasps
kept (new distinct grasps that passed every check), kept per training object, and the CPU-seconds the stages recorded
in total and per kept grasp.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import yaml

def parse_variant(text: str) -> tuple[str, dict]:
    """``NAME[:key=value,...]`` -> (name, nested overlay); values are read as YAML (numbers, booleans, words)."""
    name, _, settings = text.partition(":")
    if not name or "/" in name:
        raise SystemExit(f"loop_round_yield.py: error: --variant {text!r}: needs a name without '/' before ':'")
    overlay: dict = {}
    for item in filter(None, settings.split(",")):
        key, sep, value = item.partition("=")
        if not sep:
            raise SystemExit(f"loop_round_yield.py: error: --variant {text!r}: {item!r} is not KEY=VALUE")
        node = overlay
        *parents, leaf = key.strip().split(".")
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = yaml.safe_load(value)
    return name, overlay


def run_stage(command: str, config: dict, arguments: list[str], log_path: Path) -> None:
    from dexlite_pipeline.config import section_json
    from dexlite_pipeline.loop.config import LOOP_RULE_SECTIONS, loop_rule_sections

    rule = command.replace("-", "_")  # the config the stage's rule passes it (workflow/rules/loop.smk)
    config_json = ["--config-json", section_json(config, *loop_rule_sections(rule))] if rule in LOOP_RULE_SECTIONS else []
    full = [sys.executable, "-m", "dexlite_pipeline.cli", command, *config_json, *arguments]
    with open(log_path, "w") as log:
        done = subprocess.run(full, stdout=log, stderr=subprocess.STDOUT)
    if done.returncode != 0:
        raise SystemExit(f"loop_round_yield.py: error: {command} exited {done.returncode}; see {log_path}")


def round_yield(run_dir: Path, out: Path, config: dict, round_number: int) -> dict:
    """Run the round's training part with ``config`` into ``out``; returns the counts and CPU-seconds."""
    from dexlite_pipeline.io.grasp_store import read_grasp_store
    from dexlite_pipeline.loop.round_basics import DROP_REASONS
    from dexlite_pipeline.loop.summary import stores_cpu_seconds

    results = run_dir / "results"
    model = results / ("model/cvae.pt" if round_number == 1 else f"round_{round_number - 1}/model/cvae.pt")
    previous = results / f"round_{round_number - 1}/grasps.zarr"
    objects = ["--objects", str(results / "objects")]
    if config.get("dexgraspnet", {}).get("root"):
        objects += ["--objects", str(results / "dexgraspnet/objects")]
    lift_shards = sorted((results / "lift").glob("shard_*.zarr"))
    if round_number == 1 and not previous.exists() and lift_shards:
        previous = out.parent / "round_0_grasps.zarr"  # shared by the variants: it depends on the run alone
        if not previous.exists():
            out.parent.mkdir(parents=True, exist_ok=True)
            run_stage("loop-initial-set", config, [a for p in lift_shards for a in ("--lift", str(p))] + objects + ["--out", str(previous)],
                      out.parent / "round_0_grasps.log")  # fmt: skip
    for needed in (model, previous, results / "stability/stability.parquet"):
        if not needed.exists():
            raise SystemExit(f"loop_round_yield.py: error: {needed} does not exist (run the workflow first)")
    common = ["--stability", str(results / "stability/stability.parquet"), *objects, "--round", str(round_number), "--part", "train"]
    out.mkdir(parents=True, exist_ok=True)
    stores, validated_args = [], []
    for shard in range(int(config["shards"])):
        sample, post, validated = (out / f"{kind}_{shard:03d}.zarr" for kind in ("sample", "post", "validated"))
        shard_args = [*common, "--shard", str(shard), "--threads", "1"]
        run_stage("loop-sample", config, ["--model", str(model), *shard_args, "--out", str(sample)], out / f"sample_{shard:03d}.log")
        run_stage("loop-post-optimize", config, ["--sample", str(sample), *shard_args, "--out", str(post)], out / f"post_{shard:03d}.log")
        run_stage("loop-validate", config, ["--grasps", str(post), *shard_args, "--out", str(validated)], out / f"validate_{shard:03d}.log")
        stores += [sample, post, validated]
        validated_args += ["--validated", str(validated)]
    merged = out / "grasps.zarr"
    run_stage("loop-merge", config, ["--previous", str(previous), *validated_args, "--round", str(round_number), "--out", str(merged)], out / "merge.log")
    candidates = pd.DataFrame(read_grasp_store(merged).attrs["candidates"], columns=["object_id", "sampled", "kept", *DROP_REASONS])
    row = {column: int(candidates[column].sum()) for column in ("sampled", *DROP_REASONS)}
    row["kept"] = int(candidates["kept"].sum())  # passed every check and new (not duplicate)
    row["objects"] = len(candidates)
    row["kept_per_object"] = row["kept"] / max(len(candidates), 1)
    row["cpu_s"] = stores_cpu_seconds([str(p) for p in stores])
    row["cpu_s_per_kept"] = row["cpu_s"] / row["kept"] if row["kept"] else float("nan")
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir", type=Path, help="a finished workflow folder (config.yaml, results/)")
    parser.add_argument("out_dir", type=Path, help="where the variants' stores, logs and the table go")
    parser.add_argument("--variant", action="append", required=True, help="NAME[:KEY=VALUE,...] (repeatable)")
    parser.add_argument("--configfile", action="append", default=[], help="config overlay the run was made with (repeatable)")
    parser.add_argument("--round", type=int, default=1, help="the round to redo (its previous model and set must exist)")
    args = parser.parse_args(argv)

    from dexlite_pipeline.config import load_config, merge_config, validate_config

    base = load_config(args.run_dir / "config.yaml")
    for path in args.configfile:
        base = merge_config(base, yaml.safe_load(Path(path).read_text()) or {})
    variants = [parse_variant(text) for text in args.variant]
    configs = [validate_config(merge_config(base, overlay), where=f"variant {name}") for name, overlay in variants]  # all before any work
    rows = []
    for (name, overlay), config in zip(variants, configs):
        row = {"variant": name, "settings": json.dumps(overlay, sort_keys=True), **round_yield(args.run_dir, args.out_dir / name, config, args.round)}
        print(", ".join(f"{k} {v:.2f}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()), flush=True)
        rows.append(row)
    table = pd.DataFrame(rows)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.out_dir / "loop_round_yield.csv", index=False)
    print(table.to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
