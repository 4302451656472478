"""Lift-test results as grasp-store arrays and attributes, plus the printed summary.

Shared by ``dexlite lift-test`` and the ``lift_validate`` stage: both keep every input
grasp (invalid ones flagged, never dropped) and record the physical constants used.
"""

from __future__ import annotations

import time
from collections import Counter

import numpy as np

from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.sim.config import LiftConfig
from dexlite_pipeline.sim.lift import DIRECTIONS, run_lift_tests


def summarize(results: dict[str, np.ndarray]) -> dict:
    """Counts and rates of one lift-test run (JSON-serializable)."""
    n = int(len(results["lift_success"]))
    simulated = int(np.isfinite(results["lift_ratio"]).sum())
    success = int(np.asarray(results["lift_success"], bool).sum())
    reasons = Counter(str(r) for r in results["failure_reason"] if r)
    summary = {
        "n_grasps": n,
        "n_simulated": simulated,
        "n_success": success,
        "success_rate": success / n if n else None,
        "success_rate_of_simulated": success / simulated if simulated else None,
        "failure_reasons": dict(sorted(reasons.items(), key=lambda kv: (-kv[1], kv[0]))),
    }
    if "six_dir_success" in results:
        six = np.asarray(results["six_dir_success"], bool)
        summary["n_six_dir_success"] = int(six.sum())
        summary["six_dir_success_rate"] = float(six.mean()) if n else None
        summary["six_dir_pass_rate_by_direction"] = {d: float(v) for d, v in zip(DIRECTIONS, np.asarray(results["six_dir_passed"]).mean(axis=0))} if n else {}
    return summary


def format_summary(summary: dict, config: LiftConfig) -> str:
    """A few human-readable lines: success rate, failure reasons, six-direction rate, constants."""
    n = summary["n_grasps"]
    if not n:
        return "lift test: no grasps"
    lines = [
        f"lift test: {summary['n_success']}/{n} grasps lifted ({100 * summary['success_rate']:.1f}%); "
        f"{summary['n_simulated']} simulated"
        + (f", {100 * summary['success_rate_of_simulated']:.1f}% of those" if summary["n_simulated"] else "")
    ]
    for reason, count in summary["failure_reasons"].items():
        lines.append(f"  failed: {reason}: {count}")
    if "six_dir_success_rate" in summary:
        by_dir = ", ".join(f"{d} {100 * v:.0f}%" for d, v in summary["six_dir_pass_rate_by_direction"].items())
        lines.append(f"six-direction test: {summary['n_six_dir_success']}/{n} pass all six ({100 * summary['six_dir_success_rate']:.1f}%); {by_dir}")
    lines.append(
        f"constants: friction {config.friction}, object mass {config.object_mass_kg} kg, finger kp {config.finger_kp}, "
        f"time step {config.timestep_s} s, squeeze {config.squeeze_rad} rad, lift {config.lift_height_m} m in {config.lift_s} s"
    )
    return "\n".join(lines)


def lift_grasp_set(grasps: GraspSet, objects_dirs, config: LiftConfig, threads: int) -> tuple[GraspSet, dict]:
    """The input grasps with the lift-test arrays added, attributes recording constants and summary."""
    start = time.perf_counter()
    results = run_lift_tests(grasps, objects_dirs, config, threads)
    seconds = time.perf_counter() - start
    arrays = dict(grasps.arrays)
    previous = arrays.pop("failure_reason", None)
    if previous is not None and any(str(r) for r in previous):
        arrays["input_failure_reason"] = previous  # an upstream stage's reasons are kept, not overwritten
    arrays.update(results)
    summary = summarize(results)
    attrs = dict(grasps.attrs)
    attrs.update(
        lift_config=config.as_dict(),
        lift_summary=summary,
        lift_seconds=seconds,
        lift_seconds_per_grasp=seconds / len(grasps) if len(grasps) else None,
        lift_threads=int(threads),
    )
    if config.six_directions:
        attrs["six_dir_directions"] = list(DIRECTIONS)
    return GraspSet(arrays, attrs), summary
