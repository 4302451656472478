"""Peak resident memory of generator training against the number of training objects.

Runs ``dexlite train-cvae`` in a fresh process per point on a finished run's training inputs (its
``results/lift`` and, for a run trained from the grasp dataset, ``results/dataset`` shards, its
``results/objects`` and ``results/stability/stability.parquet``), on a seeded subset of ``COUNT`` of its
training objects (``train.max_training_objects``; 0: all) for a few optimizer steps, and reports each
process's peak resident set size (``ru_maxrss`` from ``os.wait4``) and CPU seconds. A few steps suffice: what
grows with the objects is built before the first step (clouds, grasp rays and, when any
``train.energy_weights`` is above 0, the loss's energy with its SDF bank and point sets).
``--energies`` measures the same points with ``train.energy_weights.pen`` at 1e-6 (an energy built, the loss
practically unchanged): the memory a run with weighted energies needs.

    python benchmarks/timing/train_memory.py RUN --configfile config.yaml config/profiles/household_model.yaml \
        --counts 100 300 0 --steps 20 [--energies]

Prints one Markdown row per point: objects, grasps, energy built, peak RSS (GB), CPU-s, and the memory each object adds
(MB: the growth over the mode's first point per object more).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import torch
import yaml

from dexlite_pipeline.config import merge_config, validate_config


def train_command(run: Path, config: dict, out: Path) -> list[str]:
    """The ``dexlite train-cvae`` command line of ``run``'s training inputs with ``config``'s sections."""
    results = run / "results"
    stores = sorted((results / "lift").glob("shard_*.zarr")) + sorted((results / "dataset").glob("shard_*.zarr"))
    if not stores:
        raise SystemExit(f"{results}: no lift or dataset shards (run the data stages first)")
    sections = {key: config[key] for key in ("seed", "device", "hand", "train", "scene") if key in config}
    sections["energy"] = {"self_penetration_margin_m": config["energy"]["self_penetration_margin_m"]}
    command = [sys.executable, "-m", "dexlite_pipeline.cli", "train-cvae", "--config-json", json.dumps(sections),
               "--stability", str(results / "stability" / "stability.parquet"), "--objects", str(results / "objects"),
               "--model", str(out / "cvae.pt"), "--history", str(out / "history.csv"), "--curves", str(out / "curves.png"),
               "--threads", "1"]
    for store in stores:
        command += ["--lift", str(store)]
    return command


def measure(command: list[str], log_path: Path) -> tuple[float, float]:
    """Run ``command`` (output to ``log_path``); its peak resident memory (GB) and CPU seconds (user + system)."""
    with open(log_path, "w") as log:
        process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, cwd=Path(__file__).resolve().parents[2])
        _, status, usage = os.wait4(process.pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"training failed (exit {os.waitstatus_to_exitcode(status)}): see {log_path}")
    return usage.ru_maxrss / 1024**2, usage.ru_utime + usage.ru_stime  # ru_maxrss is in KiB on Linux


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path, help="a run folder whose data stages are done")
    parser.add_argument("--configfile", nargs="+", default=["config.yaml"], help="the run's config files, in Snakemake's order")
    parser.add_argument("--counts", type=int, nargs="+", default=[0], help="training objects per point (0: all)")
    parser.add_argument("--steps", type=int, default=20, help="optimizer steps per point")
    parser.add_argument("--energies", action="store_true", help="also each point with an energy in the loss (pen at 1e-6)")
    args = parser.parse_args(argv)
    config: dict = {}
    for path in args.configfile:  # overlays in Snakemake's order, each a partial config; the merged one is validated
        config = merge_config(config, yaml.safe_load(Path(path).read_text()) or {})
    validate_config(config, " + ".join(args.configfile))
    print("| objects asked | training objects | grasps | energy built | peak RSS (GB) | CPU-s | MB per added object |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    first_point: dict[bool, tuple[int, float]] = {}  # per energy mode, the first point's objects and peak (GB)
    for count in args.counts:
        for energies in (False, True) if args.energies else (False,):
            train = merge_config(config["train"], {"max_training_objects": count, "max_steps": args.steps, "epochs": 1000})
            if energies:
                train = merge_config(train, {"energy_weights": {"pen": 1e-6}})
            with tempfile.TemporaryDirectory(prefix="train_memory_") as folder:
                out = Path(folder)
                peak_gb, cpu_s = measure(train_command(args.run, {**config, "train": train}, out), out / "train.log")
                facts = torch.load(out / "cvae.pt", weights_only=True)
            objects = len(facts["train_object_ids"])
            grasps = facts["train_grasps"] + facts["validation_grasps"]
            base_objects, base_gb = first_point.setdefault(energies, (objects, peak_gb))
            slope = f"{(peak_gb - base_gb) * 1024 / (objects - base_objects):.1f}" if objects != base_objects else "-"
            print(f"| {count or 'all'} | {objects} | {grasps} | {'yes' if energies else 'no'} | {peak_gb:.2f} | {cpu_s:.0f} | {slope} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
