"""Evaluation metrics for a set of grasps: success, contact quality, diversity, cost.

Every function takes plain numpy arrays so it can be tested on known answers and reused
outside the pipeline. Conventions (stated once, used in the CSV column names):

- rates are fractions in [0, 1]; NaN when there is nothing to measure (never 0 by default);
  the per-grasp success rates come with a 95% Wilson score interval (``_ci95_low`` /
  ``_ci95_high``) and an object-level (cluster) bootstrap 95% interval (``_boot_ci95_low`` /
  ``_boot_ci95_high``); ``evaluation.rates`` computes both and says when they differ;
- a grasp whose pose or scale is unusable (``invalid_reason`` not empty) is not simulated
  but counts as a failure in every success rate (``n_invalid`` of ``n_grasps``), so a
  method cannot raise its rate by emitting NaN poses; diversity is measured on the others;
- lengths are reported in millimetres (``_mm``), energies in the energy module's units;
- diversity follows the two papers whose numbers a reader compares against:

  * **joint-angle entropy** (DexGraspNet, "H mean"): for each of the 22 joints, the
    angles of all grasps are binned into ``bins`` equal bins spanning that joint's limit
    range (angles outside are clipped into the end bins); the Shannon entropy of the bin
    frequencies is taken in bits, H_j = -sum_b p_b log2 p_b, and the 22 values are
    averaged (DexGraspNet reports this mean and the standard deviation over joints).
    Identical poses give 0; a joint spread evenly over its range gives log2(bins)
    (6.64 bits for 100 bins). The bin count is a setting (``evaluate.entropy_bins``), not
    a number taken from the paper, and the value grows with the number of grasps until
    the histogram fills: compare only sets of similar size at the same bin count.
  * **cumulative PCA explained variance** (DexGraspBench): principal components of the
    joint-angle vectors (N, 22) of a grasp set; the fraction of total variance carried
    by the first k components. Lower means the variation is spread over more directions
    (more diverse); data on a line gives 1.0 at k = 1.

  * **distinct held grasps** (``evaluation.diversity``): the held grasps (lift success) of
    each object and scale clustered by palm pose (config ``diversity``: 2 cm / 30°); an
    object's count is its clusters summed over its scales. Rows give the total, the mean
    over the row's objects (objects with no held grasp count 0) and the total per attempt
    (per grasp of ``n_grasps``: what a user gets per grasp generated).
  * **surface coverage**: per object, the share of its surface patches that its held grasps
    touch (``evaluation.diversity``); rows give the mean over objects. It needs the
    ``touched_patches`` (N, K) and ``coverage_patches`` (N,) arrays the aggregate step
    computes from the poses; without them the columns are NaN.
  * ``held_joint_entropy_bits``: the joint-angle entropy of the held grasps only
    (DexGraspNet computes it over its successful grasps); ``joint_entropy_bits`` is over
    all valid grasps.

- **equal filtering**: every method is also counted after one energy filter, the thresholds
  of ``evaluate.filter_thresholds`` (by default those of curation and of optimization from scratch:
  E_fc < 0.3, E_dis < 5 mm, E_pen < 1 mm) applied to the evaluation's own energies, E_fc and
  E_dis with the contacts of one deterministic search for every method (``filter_E_fc``,
  ``filter_E_dis``: ``evaluation.filter_energy``). ``energy_threshold_pass_rate`` is the share of attempts
  that pass (``filtered_n_grasps`` of ``n_grasps``; invalid grasps do not pass);
  ``filtered_*`` columns are the same measures on the passing grasps only, so a method's
  ``filtered_lift_success_rate`` is held / passing, and ``filtered_distinct_held_*`` and
  ``filtered_surface_coverage_mean`` count only held grasps that pass.
- **convergence** columns: ``evaluation.convergence``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from dexlite_pipeline.energy.config import DEXGRASPNET_THRESHOLDS
from dexlite_pipeline.evaluation.config import JOINT_ENTROPY_BINS, PCA_COMPONENTS, DiversityConfig
from dexlite_pipeline.evaluation.diversity import distinct_grasp_labels
from dexlite_pipeline.evaluation.rates import cluster_bootstrap_interval, object_success_rate, rate, wilson_interval

TOUCHED_PATCHES = "touched_patches"  # (N, K) bool: surface patches each grasp touches (aggregate step)
COVERAGE_PATCHES = "coverage_patches"  # (N,) patches of each grasp's object (0: coverage not measured)


def mean_and_p95(values: np.ndarray) -> tuple[float, float]:
    """Mean and 95th percentile over the finite values (NaN, NaN when none)."""
    values = np.asarray(values, dtype=np.float64).reshape(-1)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return math.nan, math.nan
    return float(values.mean()), float(np.percentile(values, 95))


def finite_mean(values: np.ndarray) -> float:
    values = np.asarray(values, dtype=np.float64).reshape(-1)
    values = values[np.isfinite(values)]
    return float(values.mean()) if values.size else math.nan


def joint_entropy_bits(joints_rad: np.ndarray, joint_limits_rad: np.ndarray, bins: int = JOINT_ENTROPY_BINS) -> np.ndarray:
    """Per-joint histogram entropy in bits (22,) over each joint's limit range (DexGraspNet's H).

    NaN per joint when there are no grasps.
    """
    joints = np.asarray(joints_rad, dtype=np.float64)
    limits = np.asarray(joint_limits_rad, dtype=np.float64)
    if joints.ndim != 2 or limits.shape != (joints.shape[1], 2):
        raise ValueError(f"joints {joints.shape} and limits {limits.shape} do not match")
    if joints.shape[0] == 0:
        return np.full(joints.shape[1], math.nan)
    lo, hi = limits[:, 0], limits[:, 1]
    width = np.where(hi > lo, hi - lo, 1.0)
    bin_index = np.floor((joints - lo) / width * bins).astype(np.int64).clip(0, bins - 1)  # (N, J)
    counts = np.zeros((joints.shape[1], bins))
    np.add.at(counts, (np.broadcast_to(np.arange(joints.shape[1]), bin_index.shape), bin_index), 1.0)
    p = counts / joints.shape[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(p > 0, -p * np.log2(p), 0.0)
    return terms.sum(axis=1)


def pca_cumulative_explained_variance(features: np.ndarray, components: Sequence[int] = PCA_COMPONENTS) -> dict[int, float]:
    """Cumulative explained-variance ratio of the first k principal components, for each k.

    NaN when fewer than two samples or zero total variance (nothing to explain).
    """
    x = np.asarray(features, dtype=np.float64)
    if x.ndim != 2:
        raise ValueError(f"features must be (N, D), got {x.shape}")
    if x.shape[0] < 2:
        return {k: math.nan for k in components}
    centred = x - x.mean(axis=0)
    singular = np.linalg.svd(centred, compute_uv=False)
    variance = singular**2
    total = variance.sum()
    if total <= 1e-24:
        return {k: math.nan for k in components}
    cumulative = np.cumsum(variance) / total
    return {k: float(cumulative[min(k, len(cumulative)) - 1]) for k in components}


def held_flags(arrays: Mapping[str, np.ndarray]) -> np.ndarray:
    """Per grasp, True where it held (lift success); all False when the lift test was not run."""
    n = int(np.asarray(arrays["hand_pose"]).shape[0])
    if "lift_success" not in arrays:
        return np.zeros(n, dtype=bool)
    return np.asarray(arrays["lift_success"], dtype=bool) & ~invalid_flags(arrays)


# The equal filter reads E_fc and E_dis with the contacts its own search chose (evaluation.filter_energy),
# the same for every method; E_pen does not depend on the contacts.
FILTER_ARRAYS = {"E_fc": "filter_E_fc", "E_dis": "filter_E_dis", "E_pen": "E_pen"}


def filter_flags(arrays: Mapping[str, np.ndarray], thresholds: Mapping[str, float] = DEXGRASPNET_THRESHOLDS) -> np.ndarray | None:
    """Per grasp, True where every energy of ``thresholds`` (read from ``FILTER_ARRAYS``) is below its limit (NaN: fails).

    None when the filter's energies were not computed.
    """
    names = {name: FILTER_ARRAYS.get(name, name) for name in thresholds}
    if not all(array in arrays for array in names.values()):
        return None
    passing = ~invalid_flags(arrays)
    for name, limit in thresholds.items():
        values = np.asarray(arrays[names[name]], dtype=np.float64)
        with np.errstate(invalid="ignore"):
            passing &= (values <= limit) if name == "penetration_mm" else (values < limit)  # the depth may reach its cap
    return passing


def per_object_diversity(arrays: Mapping[str, np.ndarray], flags: np.ndarray, diversity: DiversityConfig = DiversityConfig()) -> dict[str, dict]:
    """Per object of ``arrays``: grasps flagged (``held``), distinct among them and the surface coverage they give.

    Distinct: greedy palm clustering per (object, scale) in table order, summed over the
    object's scales. Coverage: NaN when the patch arrays are absent or the object has none.
    """
    object_ids = np.asarray(arrays["object_id"]).astype(str)
    flags = np.asarray(flags, dtype=bool)
    rows = np.flatnonzero(flags)
    labels = np.full(len(object_ids), -1, dtype=np.int64)
    if rows.size:
        scales = np.asarray(arrays["scale"], dtype=np.float64)[rows].astype(str) if "scale" in arrays else np.full(rows.size, "")
        groups = np.char.add(np.char.add(object_ids[rows], "|"), scales)
        poses = np.asarray(arrays["hand_pose"])[rows]
        labels[rows] = distinct_grasp_labels(poses, groups, diversity.distinct_translation_m, diversity.distinct_rotation_deg)
    touched = np.asarray(arrays[TOUCHED_PATCHES], dtype=bool) if TOUCHED_PATCHES in arrays else None
    patches = np.asarray(arrays[COVERAGE_PATCHES], dtype=np.int64) if COVERAGE_PATCHES in arrays else None
    out = {}
    for object_id in np.unique(object_ids):
        mine = object_ids == object_id
        held = mine & flags
        coverage = math.nan
        if touched is not None and patches is not None and mine.any():
            count = int(patches[mine].max())
            if count > 0:
                coverage = float(touched[held][:, :count].any(axis=0).sum() / count) if held.any() else 0.0
        out[str(object_id)] = {"held": int(held.sum()), "distinct": int(len(np.unique(labels[held]))), "coverage": coverage}
    return out


def diversity_columns(
    arrays: Mapping[str, np.ndarray], flags: np.ndarray, diversity: DiversityConfig = DiversityConfig(), prefix: str = ""
) -> dict[str, float]:
    """Held count, distinct held grasps (total, mean per object, per attempt) and mean coverage of the flagged grasps.

    Means are over every object of ``arrays`` (one with no flagged grasp counts 0 distinct,
    0 coverage); per attempt divides by all grasps of ``arrays``. NaN with no grasps.
    """
    n = int(np.asarray(arrays["hand_pose"]).shape[0])
    per_object = per_object_diversity(arrays, flags, diversity) if n else {}
    distinct = np.asarray([o["distinct"] for o in per_object.values()], dtype=np.float64)
    coverage = np.asarray([o["coverage"] for o in per_object.values()], dtype=np.float64)
    return {
        f"{prefix}n_held": int(np.asarray(flags, dtype=bool).sum()),
        f"{prefix}distinct_held_total": int(distinct.sum()),
        f"{prefix}distinct_held_per_object_mean": float(distinct.mean()) if distinct.size else math.nan,
        f"{prefix}distinct_held_per_attempt": float(distinct.sum() / n) if n else math.nan,
        f"{prefix}surface_coverage_mean": finite_mean(coverage),
    }


def seconds_per_outcome(seconds_per_attempt: float, attempts: int, outcomes: int) -> float:
    """Generation seconds per outcome (e.g. per held grasp): all attempts' seconds over the outcomes they gave.

    Infinite when attempts cost time and gave none; NaN when the cost is unknown or nothing was attempted.
    """
    if not math.isfinite(seconds_per_attempt) or attempts <= 0:
        return math.nan
    total = seconds_per_attempt * attempts
    return total / outcomes if outcomes > 0 else (math.inf if total > 0 else math.nan)


def summarize_grasps(
    arrays: Mapping[str, np.ndarray],
    joint_limits_rad: np.ndarray,
    entropy_bins: int = JOINT_ENTROPY_BINS,
    pca_components: Sequence[int] = PCA_COMPONENTS,
    bootstrap_seed: int = 0,
    diversity: DiversityConfig = DiversityConfig(),
    thresholds: Mapping[str, float] = DEXGRASPNET_THRESHOLDS,
) -> dict[str, float]:
    """All per-set metrics of one (method, split) from its per-grasp arrays.

    Uses whichever of these arrays are present (absent ones give NaN columns, never a
    made-up number): lift_success, six_dir_success, penetration_mm, contact_distance_mm,
    E_fc, E_dis, E_pen, hand_pose, object_id, scale, invalid_reason, touched_patches,
    coverage_patches, initial_penetration_mm (the held grasps' start depth: median and p90). Invalid grasps are in ``n_grasps`` and fail every success rate and the
    filter; joint diversity uses the valid ones. ``thresholds``: the equal energy filter
    (energy name -> limit) behind ``energy_threshold_pass_rate`` and the ``filtered_*`` columns.
    """
    n = int(np.asarray(arrays["hand_pose"]).shape[0])
    object_ids = np.asarray(arrays["object_id"]).astype(str)
    invalid = invalid_flags(arrays)

    def column(name: str) -> np.ndarray | None:
        return np.asarray(arrays[name]) if name in arrays else None

    lift = column("lift_success")
    six = column("six_dir_success")
    pen_mean, pen_p95 = mean_and_p95(column("penetration_mm")) if "penetration_mm" in arrays else (math.nan, math.nan)
    contact = column("contact_distance_mm")
    e_fc = column("E_fc")
    joints = np.asarray(arrays["hand_pose"], dtype=np.float64)[~invalid, 6:]
    entropy = joint_entropy_bits(joints, joint_limits_rad, entropy_bins)
    pca = pca_cumulative_explained_variance(joints, pca_components)
    out = {
        "n_grasps": n,
        "n_invalid": int(invalid.sum()),
        "n_objects": int(len(np.unique(object_ids))),
        **_rate_columns("lift_success", lift, object_ids, bootstrap_seed),
        "object_success_rate": object_success_rate(object_ids, lift) if lift is not None else math.nan,
        **_rate_columns("six_dir_success", six, object_ids, bootstrap_seed),
        "penetration_mean_mm": pen_mean,
        "penetration_p95_mm": pen_p95,
        "contact_distance_mean_mm": finite_mean(contact) if contact is not None else math.nan,
        "E_fc_mean": finite_mean(e_fc) if e_fc is not None else math.nan,
        "E_fc_median": float(np.nanmedian(e_fc)) if e_fc is not None and np.isfinite(e_fc).any() else math.nan,
        "joint_entropy_bits": float(np.mean(entropy)) if len(joints) else math.nan,
        "joint_entropy_std_bits": float(np.std(entropy)) if len(joints) else math.nan,
    }
    held = held_flags(arrays)
    start_depth = np.asarray(arrays["initial_penetration_mm"], dtype=np.float64)[held] if "initial_penetration_mm" in arrays else np.zeros(0)
    start_depth = start_depth[np.isfinite(start_depth)]
    out["held_start_depth_median_mm"] = float(np.median(start_depth)) if len(start_depth) else math.nan  # the lift test's start depth
    out["held_start_depth_p90_mm"] = float(np.percentile(start_depth, 90)) if len(start_depth) else math.nan
    held_joints = np.asarray(arrays["hand_pose"], dtype=np.float64)[held, 6:]
    out["held_joint_entropy_bits"] = float(np.mean(joint_entropy_bits(held_joints, joint_limits_rad, entropy_bins))) if len(held_joints) else math.nan
    out.update(diversity_columns(arrays, held, diversity) if lift is not None else _nan_diversity(""))
    for k, value in pca.items():
        out[f"pca_explained_variance_k{k}"] = value
    passing = filter_flags(arrays, thresholds)
    out["energy_threshold_pass_rate"] = rate(passing) if passing is not None else math.nan
    out["filtered_n_grasps"] = int(passing.sum()) if passing is not None else math.nan
    for name, flags in (("lift_success", lift), ("six_dir_success", six)):  # the same rates on the passing grasps only
        kept = flags[passing] if flags is not None and passing is not None else None
        out.update(_rate_columns(f"filtered_{name}", kept, object_ids[passing] if kept is not None else object_ids, bootstrap_seed))
    if passing is not None and lift is not None:
        out.update(diversity_columns(arrays, held & passing, diversity, "filtered_"))
    else:
        out.update(_nan_diversity("filtered_"))
    return out


def _nan_diversity(prefix: str) -> dict[str, float]:
    names = ("n_held", "distinct_held_total", "distinct_held_per_object_mean", "distinct_held_per_attempt", "surface_coverage_mean")
    return {f"{prefix}{name}": math.nan for name in names}


def _rate_columns(name: str, flags: np.ndarray | None, object_ids: np.ndarray, bootstrap_seed: int) -> dict[str, float]:
    """``<name>_rate`` with its Wilson (``_ci95_*``) and object-bootstrap (``_boot_ci95_*``) intervals; NaNs when not measured."""
    if flags is None:
        return {f"{name}{suffix}": math.nan for suffix in ("_rate", "_ci95_low", "_ci95_high", "_boot_ci95_low", "_boot_ci95_high")}
    wilson = wilson_interval(flags)
    bootstrap = cluster_bootstrap_interval(object_ids, flags, bootstrap_seed)
    return {
        f"{name}_rate": rate(flags),
        f"{name}_ci95_low": wilson[0],
        f"{name}_ci95_high": wilson[1],
        f"{name}_boot_ci95_low": bootstrap[0],
        f"{name}_boot_ci95_high": bootstrap[1],
    }


def invalid_flags(arrays: Mapping[str, np.ndarray]) -> np.ndarray:
    """Per grasp, True where it was not simulated for an unusable pose or scale (``invalid_reason`` set)."""
    n = int(np.asarray(arrays["hand_pose"]).shape[0])
    if "invalid_reason" not in arrays:
        return np.zeros(n, dtype=bool)
    return np.asarray([str(r) != "" for r in arrays["invalid_reason"]], dtype=bool)


PER_OBJECT_DIVERSITY = ("n_held", "n_distinct_held", "surface_coverage", "filtered_n_grasps", "filtered_n_held", "filtered_n_distinct_held",
                        "filtered_surface_coverage")  # fmt: skip


def per_object_rows(
    arrays: Mapping[str, np.ndarray], diversity: DiversityConfig = DiversityConfig(), thresholds: Mapping[str, float] = DEXGRASPNET_THRESHOLDS
) -> list[dict]:
    """One row per object: grasp count (invalid ones among them), lift and six-direction success rates, mean penetration,
    held, distinct held and coverage per attempt, and the same after the energy filter (``thresholds``; NaN when not computed)."""
    object_ids = np.asarray(arrays["object_id"]).astype(str)
    invalid = invalid_flags(arrays)
    held = held_flags(arrays)
    passing = filter_flags(arrays, thresholds)
    measured = "lift_success" in arrays
    all_held = per_object_diversity(arrays, held, diversity) if measured else {}
    kept_held = per_object_diversity(arrays, held & passing, diversity) if measured and passing is not None else {}
    rows = []
    for object_id in np.unique(object_ids):
        mask = object_ids == object_id
        row = {"object_id": str(object_id), "n_grasps": int(mask.sum()), "n_invalid": int(invalid[mask].sum())}
        for name, key in (("lift_success", "lift_success_rate"), ("six_dir_success", "six_dir_success_rate")):
            row[key] = rate(np.asarray(arrays[name])[mask]) if name in arrays else math.nan
        row["any_lift_success"] = bool(np.asarray(arrays["lift_success"])[mask].any()) if "lift_success" in arrays else False
        row["penetration_mean_mm"] = finite_mean(np.asarray(arrays["penetration_mm"])[mask]) if "penetration_mm" in arrays else math.nan
        mine, kept = all_held.get(str(object_id)), kept_held.get(str(object_id))
        row.update({
            "n_held": mine["held"] if mine else math.nan, "n_distinct_held": mine["distinct"] if mine else math.nan,
            "surface_coverage": mine["coverage"] if mine else math.nan,
            "filtered_n_grasps": int(passing[mask].sum()) if passing is not None else math.nan,
            "filtered_n_held": kept["held"] if kept else math.nan, "filtered_n_distinct_held": kept["distinct"] if kept else math.nan,
            "filtered_surface_coverage": kept["coverage"] if kept else math.nan,
        })  # fmt: skip
        rows.append(row)
    return rows
