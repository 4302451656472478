"""Convergence of post-optimization: how soon each method's grasps meet the success thresholds.

A grasp's energy traces (one column per recorded iteration of a post-optimization store) are
checked against the DexGraspNet success thresholds (E_fc < 0.3, E_dis < 5 mm, E_pen < 1 mm,
energies in metres); a grasp "converges" at the first iteration where all hold. Per method this
gives the fraction that ever converges and the median iteration (``CONVERGENCE_COLUMNS`` of
metrics.csv), the quartile curves of E_post per iteration (convergence.csv), and how many times
fewer iterations a method needs than random starts to reach their final median E_post.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from dexlite_pipeline.energy.config import DEXGRASPNET_THRESHOLDS
from dexlite_pipeline.evaluation.rates import rate
from dexlite_pipeline.io.grasp_store import GraspSet

CONVERGENCE_COLUMNS = (
    "threshold_reached_fraction", "threshold_iteration_median", "E_post_median_initial", "E_post_median_final",
    "iterations_to_random_final_E_post", "convergence_ratio",
)  # fmt: skip


def first_iteration_meeting(traces: Mapping[str, np.ndarray], thresholds: Mapping[str, float] = DEXGRASPNET_THRESHOLDS) -> np.ndarray:
    """Per grasp, the first iteration at which every traced energy is below its threshold; -1 if never.

    ``traces`` maps energy names to (N, T) arrays, one column per recorded iteration.
    """
    missing = [name for name in thresholds if name not in traces]
    if missing:
        raise ValueError(f"energy traces missing: {', '.join(missing)}")
    meets = None
    for name, limit in thresholds.items():
        below = np.asarray(traces[name], dtype=np.float64) < limit
        meets = below if meets is None else meets & below
    reached = meets.any(axis=1)
    return np.where(reached, meets.argmax(axis=1), -1)


def trace_quartiles(trace: np.ndarray) -> np.ndarray:
    """(3, T) 25th, 50th and 75th percentiles over grasps of an (N, T) per-iteration trace."""
    trace = np.asarray(trace, dtype=np.float64)
    if trace.shape[0] == 0:
        return np.full((3, trace.shape[1] if trace.ndim == 2 else 0), math.nan)
    return np.nanpercentile(trace, [25, 50, 75], axis=0)


def convergence_summary(first_iterations: np.ndarray, iteration_of_column: np.ndarray | None = None) -> dict[str, float]:
    """Fraction of grasps that ever meet the thresholds and the median iteration at which they do."""
    first = np.asarray(first_iterations)
    reached = first >= 0
    if iteration_of_column is not None:
        iterations = np.asarray(iteration_of_column)[first[reached]]
    else:
        iterations = first[reached]
    return {
        "threshold_reached_fraction": rate(reached),
        "threshold_iteration_median": float(np.median(iterations)) if iterations.size else math.nan,
    }


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
        q = trace_quartiles(trace)
        rows += [{"method": method, "energy": name, "iteration": int(it), "q25": q[0, j], "median": q[1, j], "q75": q[2, j]} for j, it in enumerate(iterations)]
    if all(name in stacked for name in DEXGRASPNET_THRESHOLDS):
        summary = convergence_summary(first_iteration_meeting(stacked), iterations)
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
