"""The evaluation: gather each method's grasps on the evaluated objects, simulate them, tabulate.

Methods (rows of ``metrics.csv``), each read from the pipeline's own outputs:

- ``optimization`` optimization from scratch (the reference), ``results/optimized/shard_*.zarr``;
- ``cvae_raw``     raw CVAE samples, ``results/sample/shard_*.zarr`` rows with method ``cvae_raw``;
- ``cvae_post``    CVAE samples after post-optimization, ``results/post/shard_*.zarr``;
- ``random_post``  random initialization + the same post-optimization budget,
                   ``results/post/random_shard_*.zarr``;
- ``dexgraspnet``  imported DexGraspNet grasps (when configured);
- ``shipped_raw`` / ``shipped_post``  the shipped (pretrained) model's samples on held-out
                   objects it never trained on, raw and post-optimized (rows ``shipped_raw`` of
                   the sampled and post-optimized stores).

Every method goes through the same measurement: energies recomputed by one code path
(contacts = the four candidates nearest the surface, so no method is judged by its own
optimizer's bookkeeping), then the MuJoCo lift and six-direction tests with one set of
physical constants. At most ``grasps_per_object`` grasps per (method, object) are
chosen by a seeded draw, so every method is weighted alike per object. The CVAE methods
and the random-init baseline share one draw over the sampled rows, so they are compared
on the same source rows (same objects and scales; raw and refined: the same samples).
A chosen grasp with an unusable pose or scale is not simulated but stays in the set as a
failure (``invalid_reason``), so emitting NaN poses cannot raise a method's rate.

Equal filtering: every method is drawn from all its attempts (the optimization method too: all its
optimized grasps, not only those its synthesis flagged as passing) and reported twice, per
attempt and after one energy filter: the simulate step computes every grasp's filter energies
with one contact search (``evaluation.filter_energy``), the aggregate step applies
``evaluate.filter_thresholds`` to them; no method is filtered while another is not. The cost
columns divide the seconds of the stages that generated a method's attempts (see
``stage_seconds_per_grasp``) by what those attempts gave: held grasps, distinct held grasps,
and the same after the filter.
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import math
import time
from collections import Counter
from collections.abc import Mapping, Sequence

import numpy as np

from dexlite_pipeline.config import from_section
from dexlite_pipeline.io.grasp_store import GraspSet, invalid_grasp_reasons
from dexlite_pipeline.evaluation import metrics
from dexlite_pipeline.evaluation.config import LADDER_RUNGS, DiversityConfig, EvaluateConfig, WriteupProtocolConfig, draw_label
from dexlite_pipeline.evaluation.step_keys import with_evaluate_keys

log = logging.getLogger(__name__)

PURE_SYNTHESIS = "cvae_raw"  # the sampled stores' method label of pure syntheses on held-out objects
# Methods read from the sampled / post-optimized stores: method -> (the stores' row label, stage of the store).
SAMPLED_METHODS = {
    "cvae_raw": (PURE_SYNTHESIS, "sample"),
    "cvae_post": (PURE_SYNTHESIS, "post"),
    "cvae_recon": ("cvae_recon", "sample"),
    "cvae_recon_post": ("cvae_recon", "post"),
    "cvae_prior_train": ("cvae_prior_train", "sample"),
    "cvae_prior_train_post": ("cvae_prior_train", "post"),
    "shipped_raw": ("shipped_raw", "sample"),
    "shipped_post": ("shipped_raw", "post"),
}
PAIRED_METHODS = (*SAMPLED_METHODS, "random_post")  # rows correspond to rows of the sampled store
PAIRED_DRAW = "sampled_rows"  # name of the draw these methods share
SELECTED_ARRAYS = ("hand_pose", "object_id", "scale")
BUDGET_POSES = "budget_hand_pose"  # (N, S, 28) post-optimized poses after each budget iteration (post stores)
TABLE_DEPTH = "table_depth_mm"  # deepest hand point below the object's table in its resting pose (mm; both modes)
WRITEUP_PROTOCOL_SUCCESS = "writeup_protocol_lift_success"  # lift success under ``evaluate.writeup_protocol``'s physics
BUDGET_SUCCESS = "budget_lift_success"  # (N, S) lift success of those poses (1/0; NaN where a method has none)
CONVERGENCE_COLUMNS = (
    "threshold_reached_fraction", "threshold_iteration_median", "E_post_median_initial", "E_post_median_final",
    "iterations_to_random_final_E_post", "convergence_ratio",
)  # fmt: skip


def rung_of(method: str, split: str) -> str:
    """The learning-ladder rung a (method, split) row measures: fit, in_distribution, heldout, or '' (not a model row)."""
    if method in LADDER_RUNGS:
        return LADDER_RUNGS[method]
    if split == "heldout" and method in ("cvae_raw", "cvae_post", "random_post"):
        return "heldout"
    return ""


def evaluate_config_from(config: Mapping | None, keys: Sequence[str] | None = None) -> EvaluateConfig:
    """The ``evaluate`` section as a dataclass; with ``keys``, only those keys are read (the others keep defaults).

    A step passes the keys it tracks (``evaluation.step_keys``), so it computes the same from the
    rule's cut-down section as from a whole section given on the command line.
    """
    config = config or {}
    if keys is not None:
        config = with_evaluate_keys(config, keys)
    return from_section(EvaluateConfig, config.get("evaluate"), "config.evaluate")


def require_split_objects(split_of: Mapping[str, str], splits: Sequence[str], objects_dirs: Sequence) -> None:
    """Fail when an evaluated split has no object in the catalogs: it would give empty rows, not a result."""
    present = set(split_of.values())
    empty = [split for split in splits if split not in present]
    if empty:
        raise ValueError(
            f"config.evaluate.splits: no object of split {', '.join(empty)} in the catalogs of "
            f"{', '.join(map(str, objects_dirs)) or '(no objects dir)'} (their splits: {', '.join(sorted(present)) or 'none'})"
        )


def method_seed(seed: int, method: str) -> int:
    """A per-method seed that does not depend on Python's hash randomization."""
    digest = hashlib.sha256(f"{seed}:{method}".encode()).digest()
    return int.from_bytes(digest[:8], "little")


def row_priorities(seed: int, draw: str, count: int) -> np.ndarray:
    """Seeded uniform priorities of rows 0..count-1 for a named draw (lower is chosen first).

    Row k gets the k-th value of the draw's stream whatever ``count`` is, so methods that
    share a draw rank the rows they have in common alike.
    """
    return np.random.default_rng(method_seed(seed, draw)).random(count)


def select_grasps(
    grasps: GraspSet,
    method: str,
    split_of: Mapping[str, str],
    cfg: EvaluateConfig,
    seed: int,
    sample_rows: np.ndarray | None = None,
) -> GraspSet:
    """The grasps of one method on objects of the evaluated splits, at most ``grasps_per_object`` per object.

    Per object, the rows with the lowest seeded priorities are taken. With ``sample_rows``
    (each grasp's row in the sampled store, see ``sample_rows_of``) the priorities are those
    of the sampled rows in one draw shared by the paired methods, so they take the same
    source rows; otherwise the method draws over its own rows. A grasp with an unusable
    pose or scale is chosen like any other and kept with its ``invalid_reason``: it is not
    simulated and counts as a failure. Adds ``method``, ``split``, ``source_row`` (row in
    the method's grasps), ``sample_row`` (-1 when unpaired) and ``invalid_reason`` arrays.
    """
    object_ids = np.asarray([str(o) for o in grasps.object_id])
    splits = np.asarray([split_of.get(o, "unknown") for o in object_ids])
    reasons = invalid_grasp_reasons(grasps)
    candidate = np.isin(splits, list(cfg.splits_of(method)))
    if sample_rows is None:
        keys, draw = np.arange(len(grasps)), draw_label(method)  # a frozen label for a renamed method
    else:
        keys, draw = np.asarray(sample_rows, dtype=np.int64), PAIRED_DRAW
        if keys.shape != (len(grasps),):
            raise ValueError(f"{method}: {keys.shape[0]} sampled rows given for {len(grasps)} grasps")
    priority = row_priorities(seed, draw, int(keys.max()) + 1 if len(keys) else 0)[keys]
    chosen: list[int] = []
    for object_id in sorted(set(object_ids[candidate])):
        rows = np.flatnonzero(candidate & (object_ids == object_id))
        chosen.extend(sorted(rows[np.argsort(priority[rows], kind="stable")][: cfg.cap_of(method)].tolist()))
    rows = np.asarray(chosen, dtype=np.int64)
    arrays = {name: grasps.arrays[name][rows] for name in (*SELECTED_ARRAYS, BUDGET_POSES) if name in grasps.arrays}
    arrays["method"] = np.full(len(rows), method, dtype=object)
    arrays["split"] = splits[rows].astype(object)
    arrays["source_row"] = rows
    arrays["sample_row"] = keys[rows] if sample_rows is not None else np.full(len(rows), -1, np.int64)
    arrays["invalid_reason"] = reasons[rows].astype(object)
    invalid_reasons = Counter(str(r) for r in reasons[rows] if r)
    return GraspSet(arrays, {"invalid_reasons": dict(sorted(invalid_reasons.items()))})


def _labelled(store: GraspSet, label: str = PURE_SYNTHESIS) -> np.ndarray:
    """Rows of a sampled (or post-optimized) store with method label ``label``; for pure syntheses, all rows of a store
    without a method column."""
    if "method" not in store.arrays:
        return np.full(len(store), label == PURE_SYNTHESIS, dtype=bool)
    return np.asarray([str(m) for m in store.arrays["method"]]) == label


def method_grasps(method: str, sources: Sequence[GraspSet]) -> GraspSet:
    """Concatenate one method's source stores, keeping only the rows that belong to it.

    The sample (and post) stores hold both pure syntheses on held-out objects (``method ==
    cvae_raw``) and dataset expansion on train objects; only the former are the
    ``cvae_raw`` method, and their refined versions the ``cvae_post`` method. Every method
    keeps all its attempts: the optimization method's grasps that its synthesis flagged as failing
    the thresholds too (the equal filter is applied later, to every method alike).
    """
    parts = []
    for source in sources:
        subset = source
        if method in SAMPLED_METHODS:
            subset = source.select(_labelled(source, SAMPLED_METHODS[method][0]))
        kept = (*SELECTED_ARRAYS, BUDGET_POSES) if all(BUDGET_POSES in src.arrays for src in sources) else SELECTED_ARRAYS
        parts.append(GraspSet({k: subset.arrays[k] for k in kept}, subset.attrs))
    return GraspSet.concatenate(parts, attrs={})


def sample_rows_of(method: str, sources: Mapping[str, Sequence[GraspSet]], known_object_ids: set[str]) -> np.ndarray | None:
    """For a paired method, the row in the sampled stores (concatenated) of each grasp ``method_grasps`` gives.

    None for the other methods, or without sampled stores. Post-optimized stores keep one
    row per sampled row (the refined pose beside the raw one); the random-init baseline
    has one row per valid pure synthesis of the sampled store, in order, started for that
    row's object and scale (stages/post_optimize.py). Stores that do not line up with the
    sampled ones (other length, object or scale) are an error: they come from another run.
    """
    samples = list(sources.get("sample") or [])
    if method not in PAIRED_METHODS or not samples:
        return None
    sampled = _rows_of(samples)
    label, stage = SAMPLED_METHODS.get(method, (PURE_SYNTHESIS, "random_post"))
    labelled = _labelled(sampled, label)
    if stage == "sample":
        return np.flatnonzero(labelled)
    stores = list(sources.get(stage) or [])
    stored = _rows_of(stores)
    if stage == "post":
        rows = np.arange(len(sampled))
    else:
        rows = np.flatnonzero(labelled & (invalid_grasp_reasons(sampled, known_object_ids) == ""))
        if len(stored) == 0:  # the baseline was not run (post_optimize.random_baseline off)
            return np.zeros(0, dtype=np.int64)
    lined_up = len(stored) == len(rows) and np.array_equal(stored.object_id.astype(str), sampled.object_id[rows].astype(str))
    lined_up = lined_up and np.array_equal(stored.scale, sampled.scale[rows])
    if not lined_up:
        raise ValueError(f"{method}: its {len(stored)} grasps do not line up with the {len(rows)} sampled rows they refine (object or scale differ): stores of different runs?")
    return rows[_labelled(stored, label)] if stage == "post" else rows


def _rows_of(stores: Sequence[GraspSet]) -> GraspSet:
    """Pose, object, scale and (where stored) method label of ``stores``, concatenated in order."""
    kept = (*SELECTED_ARRAYS, "method")
    return GraspSet.concatenate([GraspSet({k: v for k, v in s.arrays.items() if k in kept}) for s in stores], attrs={})


def stage_seconds_per_grasp(method: str, sources: Mapping[str, Sequence[GraspSet]]) -> dict[str, float]:
    """Seconds per attempt of each stage that made a method's grasps (grasp-weighted over shards).

    Each store records its stage's wall seconds per grasp it made (``seconds_per_grasp``):
    optimization from scratch per optimized grasp (passing or not), sampling per sampled row (model
    loading and every kind of row in the shard included), post-optimization per refined
    grasp. Those stages run as one-thread jobs (``SHARD_THREADS``), so on a CPU run these are
    CPU-seconds (an upper bound when the core is shared). Not included: training, object
    preparation, the evaluation's energies (the filter) and its simulation. DexGraspNet's
    imported grasps carry no cost.
    """
    stages = {"optimization": ("optimized",), "random_post": ("random_post",), "dexgraspnet": ()}
    stages.update({m: ("sample",) if stage == "sample" else ("sample", "post") for m, (_, stage) in SAMPLED_METHODS.items()})
    out = {}
    for stage in stages[method]:
        sets = sources.get(stage, [])
        weighted = [(float(s.attrs["seconds_per_grasp"]), len(s)) for s in sets if s.attrs.get("seconds_per_grasp") is not None and len(s)]
        if weighted:
            total = sum(n for _, n in weighted)
            out[stage] = sum(t * n for t, n in weighted) / total
    return out


def simulate(
    selected: GraspSet,
    objects_dirs,
    lift_cfg,
    energy_cfg,
    device: str,
    threads: int,
    energy_batch_size: int,
    writeup_protocol: WriteupProtocolConfig | None = None,
    support_planes=None,
) -> GraspSet:
    """Energies, the equal filter's energies (``evaluation.filter_energy``) and lift (+ six-direction) results for every
    selected grasp, as one grasp set.

    Invalid grasps (``invalid_reason``) pass through both with NaN results and a failed
    lift; the seconds per grasp are per simulated (valid) grasp. ``support_planes`` (tabletop
    mode): every lift test (and the write-up's protocol's) runs with each object on its table.
    """
    from dexlite_pipeline.energy.per_grasp import evaluate_grasp_energies
    from dexlite_pipeline.evaluation.filter_energy import filter_energy_arrays
    from dexlite_pipeline.sim.lift import run_lift_tests

    arrays = dict(selected.arrays)
    if len(selected) == 0:
        return GraspSet(arrays, dict(selected.attrs))
    simulated_count = max(1, len(selected) - int(metrics.invalid_flags(arrays).sum()))
    start = time.perf_counter()
    log.info("energies of %d grasps (batches of %d) ...", len(selected), energy_batch_size)
    energies = evaluate_grasp_energies(selected, objects_dirs, device=device, batch_size=energy_batch_size, config=energy_cfg)
    energy_s = time.perf_counter() - start
    log.info("energies of %d grasps in %.1f s (%.1f grasps/s)", len(selected), energy_s, len(selected) / max(energy_s, 1e-9))
    arrays.update(energies)
    start = time.perf_counter()
    arrays.update(filter_energy_arrays(selected, objects_dirs, energy_cfg.weights, device))
    log.info("the equal filter's contact search of %d grasps in %.1f s", len(selected), time.perf_counter() - start)
    start = time.perf_counter()
    lifted = run_lift_tests(selected, objects_dirs, lift_cfg, threads, support_planes=support_planes)
    lifted.pop("table_depth_mm", None)  # measured for every mode by the caller (energy.table_clearance.grasp_table_depths)
    too_deep = np.asarray(lifted["lift_success"], bool) & (np.asarray(lifted["initial_penetration_mm"]) > 1000.0 * lift_cfg.max_initial_penetration_m + 1e-4)
    if too_deep.any():  # the lift test refuses such starts; a held one would mean the start check was bypassed
        raise RuntimeError(f"{int(too_deep.sum())} held grasps start deeper than lift.max_initial_penetration_m ({lift_cfg.max_initial_penetration_m} m)")
    arrays.update(lifted)
    lift_s = time.perf_counter() - start
    if writeup_protocol is not None and writeup_protocol.enabled:
        lenient = dataclasses.replace(lift_cfg, **writeup_protocol.lift_overrides())
        log.info("lift test of %d grasps under the write-up's protocol (friction %g, +%g rad, ratio %g)", len(selected),
                 lenient.friction, lenient.preclose_rad, lenient.success_lift_ratio)
        arrays[WRITEUP_PROTOCOL_SUCCESS] = run_lift_tests(selected, objects_dirs, lenient, threads, support_planes=support_planes)["lift_success"]
    attrs = dict(selected.attrs)
    attrs["energy_seconds_per_grasp"] = energy_s / simulated_count
    attrs["simulation_seconds_per_grasp"] = lift_s / simulated_count
    return GraspSet(arrays, attrs)


def convergence_traces(post: GraspSet) -> tuple[dict[str, np.ndarray], np.ndarray] | None:
    """Per-iteration energy traces of a post-optimization store: {name: (N, T)} and the iteration of each column.

    Reads ``energy_trace`` (the total E_post) and any ``trace_<energy>`` arrays (e.g.
    ``trace_E_fc``) with the attribute ``trace_iterations``; None when the store has no trace.
    """
    traces = {}
    for name, value in post.arrays.items():
        if np.ndim(value) != 2:
            continue
        if name == "energy_trace":
            traces["E_post"] = np.asarray(value, dtype=np.float64)
        elif name.startswith("trace_"):
            traces[name[len("trace_") :]] = np.asarray(value, dtype=np.float64)
    if not traces:
        return None
    width = next(iter(traces.values())).shape[1]
    iterations = np.asarray(post.attrs.get("trace_iterations", list(range(width))), dtype=np.int64)
    if iterations.shape != (width,):
        iterations = np.arange(width)
    return traces, iterations


def convergence_rows(method: str, post_sets: Sequence[GraspSet], split_of: Mapping[str, str], splits: Sequence[str]) -> tuple[list[dict], dict[str, float]]:
    """Quartiles of E_post per recorded iteration (rows of convergence.csv) and threshold-iteration stats."""
    traces: dict[str, list[np.ndarray]] = {}
    iterations = None
    for post in post_sets:
        found = convergence_traces(post)
        if found is None:
            continue
        keep = np.isin([split_of.get(str(o), "unknown") for o in post.object_id], list(splits))
        for name, trace in found[0].items():
            traces.setdefault(name, []).append(trace[keep])
        iterations = found[1]
    if iterations is None:
        return [], {"threshold_reached_fraction": math.nan, "threshold_iteration_median": math.nan}
    stacked = {name: np.concatenate(parts) for name, parts in traces.items() if all(p.shape[1] == len(iterations) for p in parts)}
    rows = []
    for name, trace in sorted(stacked.items()):
        q = metrics.trace_quartiles(trace)
        rows += [{"method": method, "energy": name, "iteration": int(it), "q25": q[0, j], "median": q[1, j], "q75": q[2, j]} for j, it in enumerate(iterations)]
    if all(name in stacked for name in metrics.DEXGRASPNET_THRESHOLDS):
        summary = metrics.convergence_summary(metrics.first_iteration_meeting(stacked), iterations)
    else:
        summary = {"threshold_reached_fraction": math.nan, "threshold_iteration_median": math.nan}
    if "E_post" in stacked and len(stacked["E_post"]):
        median = np.nanmedian(stacked["E_post"], axis=0)
        summary.update({"E_post_median_initial": float(median[0]), "E_post_median_final": float(median[-1])})
    return rows, summary


def iterations_to_reach(curves, method: str, level: float) -> float:
    """First recorded iteration at which a method's median E_post is at or below ``level`` (NaN if never).

    With ``level`` = the random-init baseline's final median, this compares convergence
    speed: random init needs its whole budget to get there, a better init fewer steps.
    """
    frame = curves[(curves["method"] == method) & (curves["energy"] == "E_post")].sort_values("iteration")
    below = frame[frame["median"] <= level]
    return float(below["iteration"].iloc[0]) if len(below) and math.isfinite(level) else math.nan


def convergence_ratio(random_iterations: float, method_iterations: float) -> float:
    """How many times fewer iterations a method needs than random init to reach random init's final median E_post.

    Iteration 0 counts as 1 (a start already at that level); NaN when either never gets there.
    """
    if not (math.isfinite(random_iterations) and math.isfinite(method_iterations)):
        return math.nan
    return max(random_iterations, 1.0) / max(method_iterations, 1.0)


def concatenate_shards(shards: Sequence[GraspSet]) -> GraspSet | None:
    """The simulated shards with grasps as one set (the arrays they all have); None when all are empty."""
    if not any(len(s) for s in shards):
        return None
    return GraspSet.concatenate_common(shards)[0]


def metrics_tables(
    simulated: GraspSet,
    joint_limits_rad: np.ndarray,
    cfg: EvaluateConfig,
    seconds: Mapping[str, Mapping[str, float]],
    convergence: Mapping[str, Mapping[str, float]],
    sim_seconds_per_grasp: float = math.nan,
    bootstrap_seed: int = 0,
    diversity: DiversityConfig = DiversityConfig(),
):
    """(metrics DataFrame: one row per (method, split); per-object DataFrame). ``bootstrap_seed`` seeds the object bootstrap.

    Distinct held grasps and coverage follow ``diversity``; the equal filter is ``cfg.filter_thresholds``.
    ``cpu_seconds_per_*``: ``seconds_per_grasp`` (the generating stages, per attempt) times the
    attempts, over the held / distinct held grasps they gave, per attempt and after the filter.
    """
    import pandas as pd

    thresholds = cfg.filter_thresholds.limits()

    methods = np.asarray([str(m) for m in simulated.arrays.get("method", [])])
    splits = np.asarray([str(s) for s in simulated.arrays.get("split", [])])
    rows, object_rows = [], []
    for method in cfg.methods:
        for split in cfg.splits_of(method):
            mask = (methods == method) & (splits == split)
            subset = {k: v[mask] for k, v in simulated.arrays.items()}
            row = {"method": method, "split": split, "rung": rung_of(method, split)}
            row.update(metrics.summarize_grasps(subset, joint_limits_rad, cfg.entropy_bins, cfg.pca_components, bootstrap_seed, diversity, thresholds))
            stage_times = seconds.get(method, {})
            row["seconds_per_grasp"] = sum(stage_times.values()) if stage_times else math.nan
            row["seconds_per_grasp_by_stage"] = ";".join(f"{k}={v:.4g}" for k, v in stage_times.items())
            for prefix in ("", "filtered_"):
                for outcome, column in (("held", "n_held"), ("distinct_held", "distinct_held_total")):
                    count = row[f"{prefix}{column}"]
                    row[f"{prefix}cpu_seconds_per_{outcome}_grasp"] = (
                        metrics.seconds_per_outcome(row["seconds_per_grasp"], row["n_grasps"], int(count)) if math.isfinite(count) else math.nan
                    )
            row["simulation_seconds_per_grasp"] = sim_seconds_per_grasp
            for name in FIT_ERRORS:
                values = np.asarray(subset.get(name, []), dtype=np.float64)
                values = values[np.isfinite(values)]
                statistic = np.mean if name == "fit_joint_error_rad" else np.median
                row[f"{name}_{'mean' if statistic is np.mean else 'median'}"] = float(statistic(values)) if len(values) else math.nan
            if WRITEUP_PROTOCOL_SUCCESS in subset:
                lenient = np.asarray(subset[WRITEUP_PROTOCOL_SUCCESS], dtype=bool)
                low, high = metrics.wilson_interval(lenient)
                row.update({"writeup_protocol_lift_success_rate": metrics.rate(lenient), "writeup_protocol_lift_success_ci95_low": low,
                            "writeup_protocol_lift_success_ci95_high": high})
            row.update({name: convergence.get(method, {}).get(name, math.nan) for name in CONVERGENCE_COLUMNS})
            if TABLE_DEPTH in subset:  # tabletop reachability (both modes): held grasps with no hand point below the table
                from dexlite_pipeline.tabletop import reachable_on_table

                row.update(reachable_on_table(subset["lift_success"], subset[TABLE_DEPTH]))
            rows.append(row)
            for object_row in metrics.per_object_rows(subset, diversity, thresholds) if mask.any() else []:
                object_rows.append({"method": method, "split": split, **object_row})
    per_object_columns = ["method", "split", "object_id", "n_grasps", "n_invalid", "lift_success_rate", "six_dir_success_rate", "any_lift_success",
                          "penetration_mean_mm", *metrics.PER_OBJECT_DIVERSITY]  # fmt: skip
    return pd.DataFrame(rows), pd.DataFrame(object_rows, columns=per_object_columns)


def simulate_budget(selected: GraspSet, objects_dirs, lift_cfg, threads: int, support_planes=None) -> np.ndarray:
    """(N, S) lift success (1.0 / 0.0, lift test only) of each selected grasp's pose after every budget iteration.

    The six-direction test is left out here: the budget curve asks how soon post-optimization
    reaches a grasp that holds, and the lift test alone is ten times cheaper.
    """
    import dataclasses

    from dexlite_pipeline.sim.lift import run_lift_tests

    poses = np.asarray(selected.arrays[BUDGET_POSES], dtype=np.float32)
    count, steps = poses.shape[:2]
    flat = GraspSet(
        {
            "hand_pose": poses.reshape(count * steps, -1),
            "object_id": np.repeat(np.asarray(selected.object_id, dtype=object), steps),
            "scale": np.repeat(np.asarray(selected.scale, dtype=np.float32), steps),
        },
        {},
    )
    result = run_lift_tests(flat, objects_dirs, dataclasses.replace(lift_cfg, six_directions=False), threads, support_planes=support_planes)
    return np.asarray(result["lift_success"], dtype=np.float64).reshape(count, steps)


def budget_rows(simulated: GraspSet, iterations: Sequence[int], methods: Sequence[str]) -> list[dict]:
    """Rows of budget.csv: lift success rate (Wilson 95%) of each method after each budget iteration."""
    if BUDGET_SUCCESS not in simulated.arrays or not len(iterations):
        return []
    success = np.asarray(simulated.arrays[BUDGET_SUCCESS], dtype=np.float64)
    labels = np.asarray([str(m) for m in simulated.arrays["method"]])
    rows = []
    for method in methods:
        mine = success[labels == method]
        mine = mine[np.isfinite(mine).all(axis=1)] if len(mine) else mine
        if not len(mine):
            continue
        for column, iteration in enumerate(iterations):
            flags = mine[:, column] > 0.5
            low, high = metrics.wilson_interval(flags)
            rows.append({"method": method, "iteration": int(iteration), "n_grasps": int(len(flags)),
                         "lift_success_rate": metrics.rate(flags), "lift_ci95_low": low, "lift_ci95_high": high})
    return rows


FIT_ERRORS = ("fit_rotation_error_deg", "fit_translation_error_mm", "fit_joint_error_rad")
FIT_METHODS = ("cvae_recon", "cvae_recon_post")  # rows that reproduce a known grasp (``reference_hand_pose``)


def fit_error_arrays(selected: GraspSet, method: str, sampled_reference: np.ndarray | None) -> dict[str, np.ndarray]:
    """Per-row pose errors against the known grasp a fit-rung row reconstructs; NaN for rows of other methods.

    ``sampled_reference`` is the sampled stores' ``reference_hand_pose`` (rows as in
    ``sample_row``): the training grasp each reconstruction (and its post-optimized version) stands for.
    """
    import torch

    from dexlite_pipeline.model.pose import pose_errors

    out = {name: np.full(len(selected), np.nan) for name in FIT_ERRORS}
    if method not in FIT_METHODS or sampled_reference is None or not len(selected):
        return out
    reference = np.asarray(sampled_reference, dtype=np.float32)[np.asarray(selected.arrays["sample_row"])]
    pose = np.asarray(selected.hand_pose, dtype=np.float32)
    usable = np.isfinite(reference).all(axis=1) & np.isfinite(pose).all(axis=1)
    if usable.any():
        errors = pose_errors(torch.as_tensor(pose[usable]), torch.as_tensor(reference[usable]))
        for name, values in zip(FIT_ERRORS, errors):
            out[name][usable] = values.numpy()
    return out



def coverage_arrays(simulated: GraspSet, objects_dirs, diversity: DiversityConfig) -> dict[str, np.ndarray]:
    """The surface patches each grasp touches, for the coverage columns (``metrics.TOUCHED_PATCHES`` and ``COVERAGE_PATCHES``).

    Per object: its stored surface samples split into ``diversity.coverage_patches`` patches
    (``diversity.surface_patch_labels``, in the normalized frame, so one split serves every
    scale); per valid grasp, the hand's 140 contact candidates placed by forward kinematics,
    their signed distance from the object's SDF grid, and the patches touched
    (``diversity.touched_patches``). Invalid grasps and objects whose asset cannot be read
    touch nothing and get 0 patches (coverage NaN for such an object, with a warning).
    """
    import torch

    from dexlite_pipeline.evaluation.diversity import surface_patch_labels, touched_patches
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.objects.assets import ObjectAssetError, SdfBank, load_asset

    n = len(simulated)
    touched = np.zeros((n, diversity.coverage_patches), dtype=bool)
    patches = np.zeros(n, dtype=np.int64)
    if n == 0:
        return {metrics.TOUCHED_PATCHES: touched, metrics.COVERAGE_PATCHES: patches}
    hand = ShadowHand()
    object_ids = np.asarray([str(o) for o in simulated.object_id])
    valid = ~metrics.invalid_flags(simulated.arrays)
    for object_id in sorted(set(object_ids)):
        try:
            asset = load_asset(objects_dirs, object_id)
        except ObjectAssetError as exc:
            log.warning("coverage: %s: %s; its coverage is not measured", object_id, exc)
            continue
        labels = surface_patch_labels(asset.surface_points, diversity.coverage_patches)
        rows = np.flatnonzero((object_ids == object_id) & valid)
        patches[object_ids == object_id] = int(labels.max()) + 1 if labels.size else 0
        if not rows.size or not labels.size:
            continue
        bank = SdfBank([asset])
        pose = torch.as_tensor(np.asarray(simulated.hand_pose[rows], dtype=np.float32), dtype=hand.dtype)
        scale = torch.as_tensor(np.asarray(simulated.scale[rows], dtype=np.float32), dtype=hand.dtype)
        with torch.no_grad():
            candidates = hand.contact_candidates(hand.forward(pose))
            distance, _ = bank.signed_distance(candidates, torch.zeros(len(rows), dtype=torch.long), scale, with_normal=False)
        normalized = (candidates / scale[:, None, None]).numpy()  # the surface samples' frame
        found = touched_patches(normalized, distance.numpy(), asset.surface_points, labels, diversity.coverage_contact_m)
        touched[rows, : found.shape[1]] = found
    return {metrics.TOUCHED_PATCHES: touched, metrics.COVERAGE_PATCHES: patches}
