"""Lift-test results as grasp-store arrays and attributes, plus the printed summary.

Shared by ``dexlite lift-test`` and the ``lift_validate`` stage: both keep every input
grasp (invalid ones flagged, never dropped) and record the physical constants used.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from pathlib import Path

import numpy as np

from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.sim.config import LiftConfig
from dexlite_pipeline.sim.lift import run_lift_tests
from dexlite_pipeline.sim.simulator import DIRECTIONS

log = logging.getLogger(__name__)


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
        # Per direction, of the grasps pushed that way (by default only lifted grasps are pushed, up to their first failed direction).
        pushed = np.isfinite(np.asarray(results["six_dir_translation_m"], float)).sum(axis=0)
        passed = np.asarray(results["six_dir_passed"], bool).sum(axis=0)
        summary["six_dir_pass_rate_by_direction"] = {d: float(p / t) if t else None for d, p, t in zip(DIRECTIONS, passed, pushed)}
        summary["six_dir_pushed_by_direction"] = {d: int(t) for d, t in zip(DIRECTIONS, pushed)}
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
        pushed = summary["six_dir_pushed_by_direction"]
        by_dir = ", ".join(f"{d} {100 * v:.0f}% of {pushed[d]}" for d, v in summary["six_dir_pass_rate_by_direction"].items() if v is not None)
        lines.append(f"six-direction test: {summary['n_six_dir_success']}/{n} pass all six ({100 * summary['six_dir_success_rate']:.1f}%); "
                     f"per direction, of the grasps pushed that way: {by_dir}")
    lines.append(
        f"constants: friction {config.friction}, object mass {config.object_mass_kg} kg, finger kp {config.finger_kp}, "
        f"time step {config.timestep_s} s, squeeze {config.squeeze_rad} rad, lift {config.lift_height_m} m in {config.lift_s} s"
    )
    return "\n".join(lines)


def lift_grasp_set(grasps: GraspSet, objects_dirs, config: LiftConfig, threads: int, support_planes=None,
                   known_failures: np.ndarray | None = None, hand=None) -> tuple[GraspSet, dict]:
    """The input grasps with the lift-test arrays added, attributes recording constants and summary.

    ``support_planes`` (tabletop mode): each object on its table; the grasps also record their
    support plane (NaN for an object without one, whose grasps are flagged invalid).
    ``known_failures``: reasons of grasps not to simulate (``run_lift_tests``). ``hand``: the grasps' hand model (None:
    the Shadow Hand; a ``DescribedHand`` is simulated from its own MJCF).
    """
    start = time.perf_counter()
    results = run_lift_tests(grasps, objects_dirs, config, threads, support_planes, known_failures, hand=hand)
    seconds = time.perf_counter() - start
    arrays = dict(grasps.arrays)
    previous = arrays.pop("failure_reason", None)
    if previous is not None and any(str(r) for r in previous):
        arrays["input_failure_reason"] = previous  # an upstream stage's reasons are kept, not overwritten
    arrays.update(results)
    if support_planes is not None:
        from dexlite_pipeline.tabletop import support_arrays

        arrays.update(support_arrays(support_planes, grasps.object_id, grasps.scale))
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


def check_objects_dirs(dirs: list[str]) -> None:
    """Every objects folder must exist and one at least hold prepared objects (an id missing from them is flagged per grasp)."""
    from dexlite_pipeline.objects.assets import ASSETS_DIR, available_object_ids

    for d in dirs:
        if not Path(d).is_dir():
            raise FileNotFoundError(f"{d}: objects folder not found")
    if not available_object_ids(dirs):
        raise FileNotFoundError(
            f"{', '.join(map(str, dirs))}: no prepared objects (expected {ASSETS_DIR}/<object id>/ as written by prepare-objects)"
        )


def nothing_simulated(grasps_path: str, summary: dict) -> bool:
    """True (and an error line) when the store had grasps but none could be simulated."""
    if summary["n_grasps"] and not summary["n_simulated"]:
        log.error("%s: none of the %d grasps could be simulated (see the reasons above)", grasps_path, summary["n_grasps"])
        return True
    return False


def report_invalid(grasps_path: str, failure_reason) -> None:
    """One warning line per kind of invalid grasp, so a user sees what was not simulated."""
    counts = Counter(r for r in failure_reason if str(r).startswith("invalid_grasp"))
    for reason, count in sorted(counts.items()):
        log.warning("%s: %d grasp(s) not simulated: %s", grasps_path, count, reason)


def lift_test_store(grasps_path: str, objects_dirs: list[str], config: LiftConfig, threads: int, support_planes=None, hand=None,
                    hand_record: dict | None = None) -> tuple[GraspSet, dict]:
    """Lift-test every grasp of the store at ``grasps_path``: its grasps with the results, and the summary.

    Raises FileNotFoundError when no objects folder holds prepared objects; invalid grasps
    are kept, flagged and counted in the log. ``hand``, ``hand_record``: the hand model to simulate and its record
    (``hand.choice``; None: the Shadow Hand); a store of another hand is refused in one line (``GraspStoreError``).
    """
    from dexlite_pipeline.io.grasp_store import DEFAULT_HAND, check_one_hand, read_grasp_store

    check_objects_dirs(objects_dirs)
    grasps = read_grasp_store(grasps_path)
    record = hand_record or {"hand": DEFAULT_HAND}
    check_one_hand([(f"config key hand ({record['hand']})", record), (str(grasps_path), grasps.attrs)])
    result, summary = lift_grasp_set(grasps, objects_dirs, config, threads, support_planes, hand=hand)
    report_invalid(grasps_path, result.arrays["failure_reason"])
    return result, summary
