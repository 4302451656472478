"""The two evaluation steps: simulate one shard of every method's grasps, then tabulate all shards.

- ``simulate_shard``: the shard's grasps of every method on the evaluated objects (the CVAE
  methods and the random baseline on the same sampled rows), energies recomputed, lift
  (+ six-direction) tested, with ``method``, ``split``, ``sample_row`` and ``invalid_reason``
  columns: invalid grasps stay in as failures.
- ``aggregate_evaluation``: every simulated shard plus the post-optimization traces make
  ``metrics.csv`` (one row per method and split, per attempt and after the equal energy
  filter, with distinct held grasps and surface coverage), ``per_object.csv``,
  ``convergence.csv`` (E_post quartiles per iteration), ``budget.csv`` and ``evaluation.json``.

Each step reads only its keys of the ``evaluate`` section (``evaluation.step_keys``).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from dexlite_pipeline.evaluation.step_keys import AGGREGATE_KEYS, METHOD_SOURCES, SIMULATE_KEYS, SOURCE_OPTIONS
from dexlite_pipeline.config import json_ready
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store
from dexlite_pipeline.objects.assets import object_splits

if TYPE_CHECKING:
    from dexlite_pipeline.energy.config import EnergyConfig
    from dexlite_pipeline.evaluation.config import DiversityConfig
    from dexlite_pipeline.sim.config import SceneConfig

log = logging.getLogger(__name__)

BUDGET_METHODS = ("cvae_post", "cvae_ranked_post", "random_post")  # methods whose post-optimization budget curve is simulated


def _sampled_reference(stores) -> np.ndarray | None:
    """The sampled stores' ``reference_hand_pose`` concatenated in order (rows as ``sample_row``); None when absent."""
    if not stores or not all("reference_hand_pose" in s.arrays for s in stores):
        return None
    return np.concatenate([np.asarray(s.arrays["reference_hand_pose"], np.float32).reshape(len(s), s.hand_pose.shape[1]) for s in stores])


# Per-row arrays of the sampled stores that the ranking adds (evaluator.ranking), carried to each paired method's
# simulated grasps through ``sample_row``: the learned evaluator's score of the sampled pose, its pool's kept share and
# (ranked rows) the row's place in its object's ranking.
EVALUATOR_COLUMNS = ("evaluator_score", "evaluator_kept_fraction", "evaluator_rank")


def ranked_order(method: str, sample_rows, columns: dict[str, np.ndarray]) -> np.ndarray | None:
    """For a ranked method (``selection.RANKED``), each grasp's place in the evaluator's ranking (lower first), else None."""
    from dexlite_pipeline.evaluation.selection import RANKED

    if method not in RANKED or sample_rows is None or "evaluator_rank" not in columns:
        return None
    rank = np.asarray(columns["evaluator_rank"], np.float64)[np.asarray(sample_rows, np.int64)]
    return np.where(rank >= 0, rank, np.inf)


def ranking_seconds_per_attempt(sample_stores, attempts: int) -> float:
    """Seconds of the ranking (drawing the whole pool, scoring it) of the shard's sampled stores per ranked grasp simulated."""
    seconds = sum(float((s.attrs.get("ranking") or {}).get("cpu_seconds") or 0.0) for s in sample_stores)
    return seconds / attempts if attempts else float("nan")


def _sampled_columns(stores) -> dict[str, np.ndarray]:
    """The sampled stores' ``EVALUATOR_COLUMNS`` concatenated in order (rows as ``sample_row``); empty when absent."""
    if not stores or not all(EVALUATOR_COLUMNS[0] in s.arrays for s in stores):
        return {}
    return {name: np.concatenate([np.asarray(s.arrays[name], np.float32) for s in stores]) for name in EVALUATOR_COLUMNS}


def _evaluator_arrays(selected, columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``EVALUATOR_COLUMNS`` of the selected grasps (NaN for grasps that are not sampled rows), when the stores have them."""
    if not columns:
        return {}
    rows = np.asarray(selected.arrays["sample_row"], np.int64)
    paired = rows >= 0
    out = {}
    for name, values in columns.items():
        column = np.full(len(rows), np.nan, np.float32)
        column[paired] = values[rows[paired]]
        out[name] = column
    return out


def _budget_iterations(stores) -> list[int]:
    """The budget iterations recorded by the post-optimization stores (attribute ``budget_iterations``)."""
    for store in stores:
        found = store.attrs.get("budget_iterations")
        if found:
            return [int(i) for i in found]
    return []


def simulate_shard(
    source_paths: dict[str, list[str]], objects_dirs: list[str], shard: int, config: dict, *, energy: EnergyConfig, scene: SceneConfig,
    seed: int, shards: int, device: str, threads: int = 1, stability_path: str | None = None, hand: str = "shadow",
) -> tuple[GraspSet, dict]:
    """Choose, simulate and measure the shard's grasps of every configured method, grasps of ``hand`` (config key
    ``hand``: every store must be of it, refused in one line otherwise; its model for the energies, the filter and the
    lift test's scene).

    ``source_paths``: store paths per source (keys of ``step_keys.SOURCE_OPTIONS``). ``config``:
    the config mapping (sections lift and the simulate keys of evaluate; recorded in the attributes);
    ``energy``, ``scene``, ``seed``, ``shards`` and ``device`` are its typed values. Returns the
    simulated grasps and their store attributes. With the stability table (``stability_path``)
    every grasp gets ``table_depth_mm``, how far its hand reaches below the object's table in the
    resting pose, in both modes (the reachability column); in tabletop mode (``scene.table``, the
    default) the lift tests also run with each object on its table.
    """
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.evaluation.protocol import (
        BUDGET_SUCCESS, evaluate_config_from, fit_error_arrays, require_split_objects, simulate, simulate_budget,
    )  # fmt: skip
    from dexlite_pipeline.evaluation.selection import BUDGET_POSES, method_grasps, sample_rows_of, select_grasps, stage_seconds_per_grasp
    from dexlite_pipeline.objects.assets import available_object_ids
    from dexlite_pipeline.sharding import shard_objects
    from dexlite_pipeline.sim.config import lift_config_from
    from dexlite_pipeline.energy.table_clearance import grasp_table_depths
    from dexlite_pipeline.tabletop import SupportPlanes, load_support_planes

    cfg = evaluate_config_from(config, SIMULATE_KEYS)
    lift_cfg = lift_config_from(config, six_directions=cfg.six_directions)
    energy_cfg = energy
    split_of = object_splits(objects_dirs, ok_only=False)
    require_split_objects(split_of, cfg.splits, objects_dirs)
    planes = SupportPlanes.from_stability_table(stability_path) if stability_path else load_support_planes(scene.table, None)
    table_planes = planes if scene.table else None  # the tables the lift tests use (floating: none)
    known_object_ids = available_object_ids(objects_dirs)
    sources = {key: [read_grasp_store(p) for p in source_paths.get(key, [])] for key in SOURCE_OPTIONS}
    record, hand_model = _run_hand(hand, [(p, s.attrs) for key in SOURCE_OPTIONS for p, s in zip(source_paths.get(key, []), sources[key])],
                                   device)
    if sources["dexgraspnet"]:  # one store for all shards: take this shard's objects
        mine = set()
        for store in sources["dexgraspnet"]:
            mine |= set(shard_objects([str(o) for o in store.object_id], shard, shards))
        sources["dexgraspnet"] = [s.select(np.isin([str(o) for o in s.object_id], sorted(mine))) for s in sources["dexgraspnet"]]

    sampled_reference = _sampled_reference(sources["sample"])
    evaluator_columns = _sampled_columns(sources["sample"])
    parts, seconds, invalid, missing = [], {}, {}, []
    budget_iterations: list[int] = []
    for method in cfg.methods:
        method_sources = sources[METHOD_SOURCES[method]]
        if not method_sources:
            missing.append(method)
            continue
        grasps = method_grasps(method, method_sources)
        sample_rows = sample_rows_of(method, sources, known_object_ids)
        rank = ranked_order(method, sample_rows, evaluator_columns)
        selected = select_grasps(grasps, method, split_of, cfg, seed, sample_rows, rank)
        arrays = dict(selected.arrays)
        arrays.update(fit_error_arrays(selected, method, sampled_reference))
        arrays.update(_evaluator_arrays(selected, evaluator_columns))
        budget_poses = arrays.pop(BUDGET_POSES, None)
        if budget_poses is not None and method in BUDGET_METHODS and len(selected):
            budget_iterations = budget_iterations or _budget_iterations(method_sources)
            arrays[BUDGET_SUCCESS] = simulate_budget(selected, objects_dirs, lift_cfg, threads, support_planes=table_planes, hand=hand_model)
            log.info("evaluate shard %s: %s: budget curve over iterations %s simulated", shard, method, budget_iterations)
        parts.append(GraspSet(arrays, {}))
        invalid[method] = selected.attrs["invalid_reasons"]
        seconds[method] = stage_seconds_per_grasp(method, sources)
        if rank is not None:  # the whole pool's sampling and scoring, over the ranked rows simulated
            seconds[method] = {"ranking": ranking_seconds_per_attempt(sources["sample"], len(selected)), **seconds[method]}
        n_invalid = sum(invalid[method].values())
        log.info("evaluate shard %s: %s: %d grasps (%d invalid) on %d objects", shard, method, len(selected), n_invalid, len(set(selected.object_id)))
    width = max((p.arrays[BUDGET_SUCCESS].shape[1] for p in parts if BUDGET_SUCCESS in p.arrays), default=0)
    if width:  # methods without a budget curve get NaN rows, so the shards concatenate
        for part in parts:
            part.arrays.setdefault(BUDGET_SUCCESS, np.full((len(part), width), np.nan))
    selected_all = GraspSet.concatenate(parts, attrs=record if not parts else {})
    if "method" not in selected_all.arrays:
        for name, dtype in (("method", object), ("split", object), ("source_row", np.int64), ("sample_row", np.int64), ("invalid_reason", object)):
            selected_all.arrays[name] = np.zeros(0, dtype=dtype)
    device = resolve_device(device)
    result = simulate(selected_all, objects_dirs, lift_cfg, energy_cfg, device, threads, cfg.energy_batch_size, cfg.writeup_protocol,
                      support_planes=table_planes, hand=hand_model)
    if planes is not None:
        result.arrays["table_depth_mm"] = grasp_table_depths(selected_all, planes, hand_model) * 1000.0
    if scene.table:  # the table each grasp was tested on, so that a grasp is reproducible from the store (and pictured on it)
        from dexlite_pipeline.tabletop import support_arrays

        result.arrays.update(support_arrays(planes, selected_all.object_id, selected_all.scale))
    attrs = {
        **record,
        "stage": "evaluate",
        "shard": shard,
        "config": config,
        "lift_config": lift_cfg.as_dict(),
        "method_seconds_per_grasp": seconds,
        "invalid_reasons": invalid,
        "methods_without_input": missing,
        "budget_iterations": budget_iterations,
        **{k: v for k, v in result.attrs.items() if k not in ("invalid_reasons",)},
    }
    return result, json_ready(attrs, nan_as_none=True)


def _run_hand(hand: str, named_attrs: list[tuple[str, dict]], device) -> tuple[dict, object]:
    """The hand record of config key ``hand`` and its model (None for the Shadow Hand: the callees' own, as before);
    ``GraspStoreError`` in one line when a store of ``named_attrs`` (path, attributes) is of another hand."""
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.hand.choice import SHADOW, hand_record, resolve_hand
    from dexlite_pipeline.model.hand_match import shards_hand

    shards_hand(named_attrs, hand)
    return hand_record(hand), None if str(hand) == SHADOW else resolve_hand(hand, resolve_device(device))


@dataclass
class EvaluationTables:
    """What the aggregate step writes: the tables and the JSON record."""

    metrics: pd.DataFrame
    per_object: pd.DataFrame
    convergence: pd.DataFrame
    budget: pd.DataFrame
    record: dict


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


def aggregate_evaluation(
    sim_paths: list[str], post_paths: list[str], random_post_paths: list[str], objects_dirs: list[str], config: dict, *,
    diversity: DiversityConfig, seed: int, hand: str = "shadow",
) -> EvaluationTables:
    """Metrics, per-object table, convergence curves and budget curve over all simulated shards, of ``hand`` (config key
    ``hand``: its contact candidates for the coverage, its joint limits for the joint entropy).

    ``config``: the config mapping (the aggregate keys of evaluate; recorded); ``diversity`` and
    ``seed`` (the bootstrap's) are its typed values.
    """
    from dexlite_pipeline.evaluation.convergence import convergence_ratio, convergence_rows, iterations_to_reach
    from dexlite_pipeline.evaluation.protocol import coverage_arrays, evaluate_config_from, require_split_objects
    from dexlite_pipeline.evaluation.rates import BOOTSTRAP_RESAMPLES
    from dexlite_pipeline.evaluation.tables import budget_rows, concatenate_shards, metrics_tables
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.io.grasp_store import empty_grasp_set

    cfg = evaluate_config_from(config, AGGREGATE_KEYS)
    shards = [read_grasp_store(p) for p in sim_paths]
    _, hand_model = _run_hand(hand, [(p, s.attrs) for p, s in zip(sim_paths, shards)], "cpu")
    # A method with no input in any shard (e.g. dexgraspnet when not configured) gets no row.
    absent = set.intersection(*(set(s.attrs.get("methods_without_input") or []) for s in shards))
    cfg = dataclasses.replace(cfg, methods=tuple(m for m in cfg.methods if m not in absent))
    simulated = concatenate_shards(shards)
    if simulated is None:
        simulated = empty_grasp_set()
    simulated.arrays.update(coverage_arrays(simulated, objects_dirs, diversity, hand=hand_model))
    seconds = _weighted_method_seconds(shards)
    sim_counts = [(s.attrs.get("simulation_seconds_per_grasp"), len(s)) for s in shards if len(s)]
    sim_total = sum(n for t, n in sim_counts if t is not None)
    sim_seconds = sum(t * n for t, n in sim_counts if t is not None) / sim_total if sim_total else math.nan

    split_of = object_splits(objects_dirs, ok_only=False)
    require_split_objects(split_of, cfg.splits, objects_dirs)
    convergence, curve_rows = {}, []
    for method, paths in (("cvae_post", post_paths), ("random_post", random_post_paths)):
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
    joint_limits = (ShadowHand() if hand_model is None else hand_model).joint_limits.cpu().numpy()
    bootstrap_seed = seed
    metrics_df, per_object_df = metrics_tables(simulated, joint_limits, cfg, seconds, convergence, sim_seconds, bootstrap_seed, diversity)
    budget_iterations = next((s.attrs.get("budget_iterations") for s in shards if s.attrs.get("budget_iterations")), [])
    budget = pd.DataFrame(
        budget_rows(simulated, budget_iterations, BUDGET_METHODS),
        columns=["method", "iteration", "n_grasps", "lift_success_rate", "lift_ci95_low", "lift_ci95_high"],
    )
    record = {
        "config": config,
        "evaluated_methods": list(cfg.methods),
        "bootstrap": {"resamples": BOOTSTRAP_RESAMPLES, "seed": bootstrap_seed, "cluster": "object"},
        "diversity": dataclasses.asdict(diversity),
        "filter_thresholds": cfg.filter_thresholds.limits(),
        "lift_config": next((s.attrs.get("lift_config") for s in shards if s.attrs.get("lift_config")), {}),
        "shards": [str(p) for p in sim_paths],
    }
    return EvaluationTables(metrics_df, per_object_df, curves, budget, json_ready(record, nan_as_none=True))


def write_evaluation(tables: EvaluationTables, metrics_path, per_object_path, convergence_path, budget_path, record_path) -> None:
    """Each table to its CSV and the record to its JSON file, atomically."""
    from dexlite_pipeline.atomic import atomic_path

    for frame, path in ((tables.metrics, metrics_path), (tables.per_object, per_object_path), (tables.convergence, convergence_path), (tables.budget, budget_path)):
        with atomic_path(path) as tmp:
            frame.to_csv(tmp, index=False, float_format="%.6g")
    with atomic_path(record_path) as tmp:
        tmp.write_text(json.dumps(tables.record, indent=2, sort_keys=True))
