"""``dexlite evaluate``: simulate every method's grasps on held-out objects and tabulate the metrics.

Two steps, so that the heavy simulation is sharded like the other grasp-heavy stages:

- ``--step simulate --shard K``: reads the K-th shard of every method's grasp stores,
  chooses the grasps on the evaluated objects (the CVAE methods and the random baseline
  on the same sampled rows), recomputes energies, runs the lift (+ six-direction) test,
  writes ``results/eval/sim/shard_K.zarr`` (with ``method``, ``split``, ``sample_row`` and
  ``invalid_reason`` columns: invalid grasps stay in as failures);
- ``--step aggregate``: reads all simulated shards plus the post-optimization traces and
  writes ``metrics.csv`` (one row per method and split), ``per_object.csv`` and
  ``convergence.csv`` (E_post quartiles per iteration) into ``--out-dir``.

Each step reads only its keys of the ``evaluate`` section (``report.steps``), the keys its
rule tracks, so a report-only setting does not rerun the simulation.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import math
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

SOURCE_OPTIONS = {
    "seed": "seed",
    "sample": "sample",
    "post": "post",
    "random_post": "random-post",
    "dexgraspnet": "dexgraspnet",
}
BUDGET_METHODS = ("cvae_post", "random_post")  # methods whose post-optimization budget curve is simulated
METHOD_SOURCES = {
    "seed": "seed", "random_post": "random_post", "dexgraspnet": "dexgraspnet",
    "cvae_raw": "sample", "cvae_recon": "sample", "cvae_prior_train": "sample",
    "cvae_post": "post", "cvae_recon_post": "post", "cvae_prior_train_post": "post",
}  # fmt: skip


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--step", choices=("simulate", "aggregate"), required=True)
    parser.add_argument("--config-json", default="{}", help="config sections (seed, device, shards, evaluate, lift, energy) as JSON")
    parser.add_argument("--objects", action="append", default=[], help="prepared objects dir (repeatable); their catalogs give the splits")
    for key, option in SOURCE_OPTIONS.items():
        parser.add_argument(f"--{option}", dest=key, action="append", default=[], help=f"{key} grasp store(s) (repeatable)")
    parser.add_argument("--shard", type=int, default=None, help="simulate: shard index (selects the DexGraspNet objects of this shard)")
    parser.add_argument("--sim", action="append", default=[], help="aggregate: simulated shard store(s)")
    parser.add_argument("--out", help="simulate: output grasp store")
    parser.add_argument("--out-dir", help="aggregate: folder for metrics.csv, per_object.csv, convergence.csv")


def split_map(objects_dirs) -> dict[str, str]:
    """Object id -> split ('train' / 'heldout') from the catalogs of the objects dirs (first wins)."""
    from dexlite_pipeline.objects.assets import CATALOG_NAME, read_catalog

    out: dict[str, str] = {}
    for directory in objects_dirs:
        if not (Path(directory) / CATALOG_NAME).exists():
            log.warning("%s: no object catalog; its objects have split 'unknown'", directory)
            continue
        catalog = read_catalog(directory)
        if "split" not in catalog.columns:
            continue
        for object_id, split in zip(catalog["object_id"].astype(str), catalog["split"].astype(str)):
            out.setdefault(object_id, split)
    return out


def _read_sources(args) -> dict[str, list]:
    from dexlite_pipeline.io.grasp_store import read_grasp_store

    return {key: [read_grasp_store(p) for p in getattr(args, key)] for key in SOURCE_OPTIONS}


def _simulate(args, config: dict) -> int:
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.energy.grasp_energy import EnergyConfig
    from dexlite_pipeline.io.grasp_store import GraspSet, write_grasp_store
    from dexlite_pipeline.config import from_section
    from dexlite_pipeline.objects.assets import available_object_ids
    from dexlite_pipeline.report.evaluation import (
        BUDGET_POSES, BUDGET_SUCCESS, evaluate_config_from, method_grasps, require_split_objects, sample_rows_of, select_grasps,
        fit_error_arrays, simulate, simulate_budget, stage_seconds_per_grasp,
    )  # fmt: skip
    from dexlite_pipeline.report.steps import SIMULATE_KEYS
    from dexlite_pipeline.sharding import shard_objects
    from dexlite_pipeline.sim.config import lift_config_from

    if not args.out or args.shard is None:
        raise ValueError("evaluate --step simulate needs --out and --shard")
    cfg = evaluate_config_from(config, SIMULATE_KEYS)
    lift_cfg = lift_config_from(config, six_directions=cfg.six_directions)
    energy_cfg = from_section(EnergyConfig, config.get("energy"), "config.energy")
    seed = int(config.get("seed") or 0)
    split_of = split_map(args.objects)
    require_split_objects(split_of, cfg.splits, args.objects)
    known_object_ids = available_object_ids(args.objects)
    sources = _read_sources(args)
    if sources["dexgraspnet"]:  # one store for all shards: take this shard's objects
        shard_count = int(config.get("shards") or 1)
        mine = set()
        for store in sources["dexgraspnet"]:
            mine |= set(shard_objects([str(o) for o in store.object_id], args.shard, shard_count))
        sources["dexgraspnet"] = [s.select(np.isin([str(o) for o in s.object_id], sorted(mine))) for s in sources["dexgraspnet"]]

    sampled_reference = _sampled_reference(sources["sample"])
    parts, seconds, invalid, missing = [], {}, {}, []
    budget_iterations: list[int] = []
    for method in cfg.methods:
        method_sources = sources[METHOD_SOURCES[method]]
        if not method_sources:
            missing.append(method)
            continue
        grasps = method_grasps(method, method_sources, cfg.seed_passing_only)
        selected = select_grasps(grasps, method, split_of, cfg, seed, sample_rows_of(method, sources, known_object_ids))
        arrays = dict(selected.arrays)
        arrays.update(fit_error_arrays(selected, method, sampled_reference))
        budget_poses = arrays.pop(BUDGET_POSES, None)
        if budget_poses is not None and method in BUDGET_METHODS and len(selected):
            budget_iterations = budget_iterations or _budget_iterations(method_sources)
            arrays[BUDGET_SUCCESS] = simulate_budget(selected, args.objects, lift_cfg, args.threads or 1)
            log.info("evaluate shard %s: %s: budget curve over iterations %s simulated", args.shard, method, budget_iterations)
        parts.append(GraspSet(arrays, {}))
        invalid[method] = selected.attrs["invalid_reasons"]
        seconds[method] = stage_seconds_per_grasp(method, sources, cfg.seed_passing_only)
        n_invalid = sum(invalid[method].values())
        log.info("evaluate shard %s: %s: %d grasps (%d invalid) on %d objects", args.shard, method, len(selected), n_invalid, len(set(selected.object_id)))
    width = max((p.arrays[BUDGET_SUCCESS].shape[1] for p in parts if BUDGET_SUCCESS in p.arrays), default=0)
    if width:  # methods without a budget curve get NaN rows, so the shards concatenate
        for part in parts:
            part.arrays.setdefault(BUDGET_SUCCESS, np.full((len(part), width), np.nan))
    selected_all = GraspSet.concatenate(parts, attrs={})
    if "method" not in selected_all.arrays:
        for name, dtype in (("method", object), ("split", object), ("source_row", np.int64), ("sample_row", np.int64), ("invalid_reason", object)):
            selected_all.arrays[name] = np.zeros(0, dtype=dtype)
    device = resolve_device(config.get("device") or "auto")
    result = simulate(selected_all, args.objects, lift_cfg, energy_cfg, device, args.threads or 1, cfg.energy_batch_size, cfg.seed_protocol)
    attrs = {
        "stage": "evaluate",
        "shard": args.shard,
        "config": config,
        "lift_config": lift_cfg.as_dict(),
        "method_seconds_per_grasp": seconds,
        "invalid_reasons": invalid,
        "methods_without_input": missing,
        "budget_iterations": budget_iterations,
        **{k: v for k, v in result.attrs.items() if k not in ("invalid_reasons",)},
    }
    write_grasp_store(args.out, result, _json_safe(attrs))
    summary = {m: int((np.asarray(result.arrays["method"]) == m).sum()) for m in cfg.methods}
    print(f"evaluate shard {args.shard}: simulated {len(result)} grasps {summary} -> {args.out}")
    return 0


def _sampled_reference(stores) -> np.ndarray | None:
    """The sampled stores' ``reference_hand_pose`` concatenated in order (rows as ``sample_row``); None when absent."""
    if not stores or not all("reference_hand_pose" in s.arrays for s in stores):
        return None
    return np.concatenate([np.asarray(s.arrays["reference_hand_pose"], np.float32).reshape(len(s), 28) for s in stores])


def _budget_iterations(stores) -> list[int]:
    """The budget iterations recorded by the post-optimization stores (attribute ``budget_iterations``)."""
    for store in stores:
        found = store.attrs.get("budget_iterations")
        if found:
            return [int(i) for i in found]
    return []


def _json_safe(value):
    """Attributes as plain JSON values: numpy scalars unwrapped, NaN as None (infinity kept)."""
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        value = value.item()
    if isinstance(value, float) and math.isnan(value):
        return None
    return value


def _aggregate(args, config: dict) -> int:
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.io.atomic import atomic_path
    from dexlite_pipeline.io.grasp_store import empty_grasp_set, read_grasp_store
    from dexlite_pipeline.report.evaluation import (
        budget_rows, concatenate_shards, convergence_ratio, convergence_rows, evaluate_config_from, iterations_to_reach, metrics_tables,
        require_split_objects,
    )  # fmt: skip
    from dexlite_pipeline.report.metrics import BOOTSTRAP_RESAMPLES
    from dexlite_pipeline.report.steps import AGGREGATE_KEYS

    import pandas as pd

    if not args.out_dir or not args.sim:
        raise ValueError("evaluate --step aggregate needs --sim and --out-dir")
    cfg = evaluate_config_from(config, AGGREGATE_KEYS)
    shards = [read_grasp_store(p) for p in args.sim]
    # A method with no input in any shard (e.g. dexgraspnet when not configured) gets no row.
    absent = set.intersection(*(set(s.attrs.get("methods_without_input") or []) for s in shards))
    cfg = dataclasses.replace(cfg, methods=tuple(m for m in cfg.methods if m not in absent))
    simulated = concatenate_shards(shards)
    if simulated is None:
        simulated = empty_grasp_set()
    seconds = _weighted_method_seconds(shards)
    sim_counts = [(s.attrs.get("simulation_seconds_per_grasp"), len(s)) for s in shards if len(s)]
    sim_total = sum(n for t, n in sim_counts if t is not None)
    sim_seconds = sum(t * n for t, n in sim_counts if t is not None) / sim_total if sim_total else math.nan

    split_of = split_map(args.objects)
    require_split_objects(split_of, cfg.splits, args.objects)
    convergence, curve_rows = {}, []
    for method, paths in (("cvae_post", args.post), ("random_post", args.random_post)):
        if method in cfg.methods and paths:
            rows, summary = convergence_rows(method, [read_grasp_store(p) for p in paths], split_of, cfg.splits)
            curve_rows += rows
            convergence[method] = summary
    curves = pd.DataFrame(curve_rows, columns=["method", "energy", "iteration", "q25", "median", "q75"])
    baseline_final = convergence.get("random_post", {}).get("E_post_median_final", math.nan)
    for method, summary in convergence.items():
        summary["iterations_to_random_final_E_post"] = iterations_to_reach(curves, method, baseline_final)
    random_needs = convergence.get("random_post", {}).get("iterations_to_random_final_E_post", math.nan)
    for method, summary in convergence.items():
        summary["convergence_ratio"] = convergence_ratio(random_needs, summary["iterations_to_random_final_E_post"])
    joint_limits = ShadowHand().joint_limits.cpu().numpy()
    bootstrap_seed = int(config.get("seed") or 0)
    metrics_df, per_object_df = metrics_tables(simulated, joint_limits, cfg, seconds, convergence, sim_seconds, bootstrap_seed)
    budget_iterations = next((s.attrs.get("budget_iterations") for s in shards if s.attrs.get("budget_iterations")), [])
    budget = pd.DataFrame(
        budget_rows(simulated, budget_iterations, BUDGET_METHODS),
        columns=["method", "iteration", "n_grasps", "lift_success_rate", "lift_ci95_low", "lift_ci95_high"],
    )
    out_dir = Path(args.out_dir)
    for name, frame in (("metrics.csv", metrics_df), ("per_object.csv", per_object_df), ("convergence.csv", curves), ("budget.csv", budget)):
        with atomic_path(out_dir / name) as tmp:
            frame.to_csv(tmp, index=False, float_format="%.6g")
    lift_attrs = next((s.attrs.get("lift_config") for s in shards if s.attrs.get("lift_config")), {})
    with atomic_path(out_dir / "evaluation.json") as tmp:
        record = {
            "config": config,
            "evaluated_methods": list(cfg.methods),
            "bootstrap": {"resamples": BOOTSTRAP_RESAMPLES, "seed": bootstrap_seed, "cluster": "object"},
            "lift_config": lift_attrs,
            "shards": [str(p) for p in args.sim],
        }
        tmp.write_text(json.dumps(_json_safe(record), indent=2, sort_keys=True))
    with_columns = ["method", "split", "n_grasps", "n_invalid", "lift_success_rate", "six_dir_success_rate", "penetration_mean_mm", "seconds_per_grasp"]
    print(metrics_df[with_columns].to_string(index=False))
    return 0


def _weighted_method_seconds(shards) -> dict[str, dict[str, float]]:
    """Stage seconds per grasp of each method, averaged over shards weighted by their grasp counts."""
    totals: dict[str, dict[str, list[float]]] = {}
    for shard in shards:
        methods = np.asarray([str(m) for m in shard.arrays.get("method", [])])
        for method, stages in (shard.attrs.get("method_seconds_per_grasp") or {}).items():
            weight = max(int((methods == method).sum()), 1)
            for stage, value in stages.items():
                if value is not None:
                    acc = totals.setdefault(method, {}).setdefault(stage, [0.0, 0.0])
                    acc[0] += float(value) * weight
                    acc[1] += weight
    return {m: {s: v[0] / v[1] for s, v in stages.items()} for m, stages in totals.items()}


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.config import parse_config_json

    config = parse_config_json(args.config_json)
    if args.step == "simulate":
        return _simulate(args, config)
    return _aggregate(args, config)
