"""The evaluation's tables over the simulated grasps of all shards: metrics.csv (one row per method and split,
with its learning-ladder rung), per_object.csv and budget.csv (lift success after each budget iteration).

A row's measures come from ``evaluation.metrics``, its convergence columns from ``evaluation.convergence``;
the protocol behind them is described in ``evaluation.protocol``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from dexlite_pipeline.evaluation import metrics, rates
from dexlite_pipeline.evaluation.config import LADDER_RUNGS, DiversityConfig, EvaluateConfig
from dexlite_pipeline.evaluation.convergence import CONVERGENCE_COLUMNS
from dexlite_pipeline.evaluation.protocol import BUDGET_SUCCESS, FIT_ERRORS, TABLE_DEPTH, WRITEUP_PROTOCOL_SUCCESS
from dexlite_pipeline.io.grasp_store import GraspSet


def rung_of(method: str, split: str) -> str:
    """The learning-ladder rung a (method, split) row measures: fit, in_distribution, heldout, or '' (not a model row)."""
    if method in LADDER_RUNGS:
        return LADDER_RUNGS[method]
    if split == "heldout" and method in ("cvae_raw", "cvae_post", "random_post"):
        return "heldout"
    return ""


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
                low, high = rates.wilson_interval(lenient)
                row.update({"writeup_protocol_lift_success_rate": rates.rate(lenient), "writeup_protocol_lift_success_ci95_low": low,
                            "writeup_protocol_lift_success_ci95_high": high})
            row.update({name: convergence.get(method, {}).get(name, math.nan) for name in CONVERGENCE_COLUMNS})
            row.update(evaluator_columns(subset))
            if TABLE_DEPTH in subset:  # tabletop reachability (both modes): held grasps with no hand point below the table
                from dexlite_pipeline.tabletop import reachable_on_table

                row.update(reachable_on_table(subset["lift_success"], subset[TABLE_DEPTH]))
            rows.append(row)
            for object_row in metrics.per_object_rows(subset, diversity, thresholds) if mask.any() else []:
                object_rows.append({"method": method, "split": split, **object_row})
    per_object_columns = ["method", "split", "object_id", "n_grasps", "n_invalid", "lift_success_rate", "six_dir_success_rate", "any_lift_success",
                          "penetration_mean_mm", *metrics.PER_OBJECT_DIVERSITY]  # fmt: skip
    return pd.DataFrame(rows), pd.DataFrame(object_rows, columns=per_object_columns)


CALIBRATION_BINS = (0.0, 0.2, 0.4, 0.6, 0.8, 1.0)  # the evaluator's predicted probability of "held", binned for calibration


def evaluator_columns(subset: Mapping[str, np.ndarray]) -> dict:
    """How well the learned evaluator's score of each sampled pose (``evaluator_score``) foretells its outcome, for a
    method's grasps that carry one: ROC AUC for "held" (and six directions), the held rate among the best-scored
    share its ranking keeps (``evaluator_kept_fraction``) against the rate of all, and calibration per score bin
    ("low-high: predicted/observed (n)"). Empty when no grasp has a score."""
    from dexlite_pipeline.evaluation.ranking import precision_at_fraction, roc_auc

    score = np.asarray(subset.get("evaluator_score", []), dtype=np.float64)
    if not len(score) or not np.isfinite(score).any():
        return {}
    tested = np.isfinite(score)
    if "invalid_reason" in subset:
        tested &= np.asarray([not str(r) for r in subset["invalid_reason"]], dtype=bool)
    held = np.asarray(subset["lift_success"], dtype=bool)[tested]
    score = score[tested]
    out = {"evaluator_scored": int(tested.sum()), "evaluator_auc_held": roc_auc(score, held)}
    if "six_dir_success" in subset:
        out["evaluator_auc_six_dir"] = roc_auc(score, np.asarray(subset["six_dir_success"], dtype=bool)[tested])
    fraction = float(np.nanmean(np.asarray(subset.get("evaluator_kept_fraction", [np.nan]), dtype=np.float64)))
    if math.isfinite(fraction):
        out["evaluator_kept_fraction"] = fraction
        out["evaluator_held_rate_at_kept"] = precision_at_fraction(score, held, fraction)
    out["evaluator_held_rate_all"] = float(held.mean()) if len(held) else math.nan
    cells = []
    for low, high in zip(CALIBRATION_BINS[:-1], CALIBRATION_BINS[1:]):
        inside = (score >= low) & ((score < high) if high < 1.0 else (score <= high))
        if inside.any():
            cells.append(f"{low:.1f}-{high:.1f}: {score[inside].mean():.2f}/{held[inside].mean():.2f} ({int(inside.sum())})")
    out["evaluator_calibration"] = "; ".join(cells)
    return out


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
            low, high = rates.wilson_interval(flags)
            rows.append({"method": method, "iteration": int(iteration), "n_grasps": int(len(flags)),
                         "lift_success_rate": rates.rate(flags), "lift_ci95_low": low, "lift_ci95_high": high})
    return rows
