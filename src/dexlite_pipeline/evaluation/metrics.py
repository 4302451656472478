"""Evaluation metrics for a set of grasps: success, contact quality, diversity, cost, convergence.

Every function takes plain numpy arrays so it can be tested on known answers and reused
outside the pipeline. Conventions (stated once, used in the CSV column names):

- rates are fractions in [0, 1]; NaN when there is nothing to measure (never 0 by default);
  the per-grasp success rates come with a 95% Wilson score interval (``_ci95_low`` /
  ``_ci95_high``): with 80 grasps a rate of 20% is 12–30%, so a difference of a few points
  between methods is not a finding. Wilson treats the grasps as independent, but they come
  in clusters (16 each from 5 objects) and grasps of one object succeed or fail together,
  so the rates also get an object-level (cluster) bootstrap 95% interval
  (``_boot_ci95_low`` / ``_boot_ci95_high``): objects resampled with replacement. It is
  wider than Wilson's when success depends strongly on the object (two of five objects
  always hold, three never: 0–80% against Wilson's 30–51%); with as few as 5 objects it
  is itself rough (it sees only the spread the sampled objects show) and can come out
  narrower, so read the two together;
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
- **convergence**: the DexGraspNet success thresholds (E_fc < 0.3, E_dis < 5 mm,
  E_pen < 1 mm, energies in metres) are checked per grasp per iteration of a post-
  optimization trace; a grasp "converges" at the first iteration where all hold.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from dexlite_pipeline.energy.config import DEXGRASPNET_THRESHOLDS
from dexlite_pipeline.evaluation.config import JOINT_ENTROPY_BINS, PCA_COMPONENTS, DiversityConfig
from dexlite_pipeline.evaluation.diversity import distinct_grasp_labels

TOUCHED_PATCHES = "touched_patches"  # (N, K) bool: surface patches each grasp touches (aggregate step)
COVERAGE_PATCHES = "coverage_patches"  # (N,) patches of each grasp's object (0: coverage not measured)

BOOTSTRAP_RESAMPLES = 4000


def rate(flags: np.ndarray) -> float:
    """Fraction of true values; NaN for an empty array."""
    flags = np.asarray(flags, dtype=bool).reshape(-1)
    return float(flags.mean()) if flags.size else math.nan


def wilson_interval(flags: np.ndarray, z: float = 1.959964) -> tuple[float, float]:
    """95% (for the default z) Wilson score interval of the success fraction of ``flags``; NaNs when empty.

    Unlike the normal approximation it stays inside [0, 1] and is not degenerate at 0 or
    all successes: 0 of 10 gives (0, 0.278).
    """
    flags = np.asarray(flags, dtype=bool).reshape(-1)
    n = flags.size
    if n == 0:
        return math.nan, math.nan
    p = float(flags.mean())
    denominator = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denominator
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denominator
    return max(0.0, centre - half), min(1.0, centre + half)


def cluster_bootstrap_interval(
    cluster_ids: np.ndarray, flags: np.ndarray, seed: int, resamples: int = BOOTSTRAP_RESAMPLES, level: float = 0.95
) -> tuple[float, float]:
    """Percentile interval of the success fraction when whole clusters (objects) are resampled with replacement.

    Each resample draws as many clusters as there are and pools their grasps, so the
    spread reflects how much success varies between objects, not only between grasps.
    Seeded, so the same inputs give the same interval. NaNs when empty; a single
    cluster gives its own rate at both ends (nothing to resample between).
    """
    flags = np.asarray(flags, dtype=bool).reshape(-1)
    if flags.size == 0:
        return math.nan, math.nan
    _, cluster = np.unique(np.asarray(cluster_ids).astype(str), return_inverse=True)
    n_clusters = int(cluster.max()) + 1
    grasps = np.bincount(cluster, minlength=n_clusters).astype(np.float64)
    successes = np.bincount(cluster, weights=flags.astype(np.float64), minlength=n_clusters)
    draws = np.random.default_rng(seed).integers(0, n_clusters, size=(resamples, n_clusters))
    offsets = (np.arange(resamples)[:, None] * n_clusters + draws).ravel()
    multiplicity = np.bincount(offsets, minlength=resamples * n_clusters).reshape(resamples, n_clusters)
    rates = (multiplicity @ successes) / (multiplicity @ grasps)
    tail = (1.0 - level) / 2 * 100
    low, high = np.percentile(rates, [tail, 100 - tail])
    return float(low), float(high)


def object_success_rate(object_ids: np.ndarray, success: np.ndarray) -> float:
    """Fraction of objects with at least one successful grasp; NaN with no grasps."""
    object_ids = np.asarray(object_ids).astype(str)
    success = np.asarray(success, dtype=bool)
    if object_ids.size == 0:
        return math.nan
    unique, inverse = np.unique(object_ids, return_inverse=True)
    any_success = np.zeros(len(unique), dtype=bool)
    np.logical_or.at(any_success, inverse, success)
    return float(any_success.mean())


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


# ---------------------------------------------------------------- display helpers (report)
# Readable names for the method ids of metrics.csv; an id not listed here is shown by
# ``method_label``'s fallback (words of the id, "+ post-optimization" for a ``_post`` suffix).
METHOD_LABELS = {
    "optimization": "Optimization from scratch",
    "cvae_raw": "CVAE samples, raw",
    "cvae_post": "CVAE samples + post-optimization",
    "random_post": "Random start + post-optimization",
    "dexgraspnet": "DexGraspNet grasps (imported)",
    "cvae_recon": "CVAE reconstructions, raw",
    "cvae_recon_post": "CVAE reconstructions + post-optimization",
    "cvae_prior_train": "CVAE samples on training objects, raw",
    "cvae_prior_train_post": "CVAE samples on training objects + post-optimization",
    "shipped_raw": "Shipped model's samples, raw",
    "shipped_post": "Shipped model's samples + post-optimization",
}
SPLIT_LABELS = {"heldout": "held-out objects", "train": "training objects"}
# The learning ladder's rungs (metrics.csv column ``rung``), in the order they are read.
RUNG_LABELS = {
    "fit": "1 · fit: training grasps encoded and decoded",
    "in_distribution": "2 · in distribution: samples on training objects",
    "heldout": "3 · held out: samples on unseen objects",
}


def method_label(method: str) -> str:
    """A reader's name for a method id (``cvae_post`` -> "CVAE samples + post-optimization")."""
    method = str(method)
    if method in METHOD_LABELS:
        return METHOD_LABELS[method]
    base, post = (method[: -len("_post")], True) if method.endswith("_post") else (method, False)
    words = " ".join("CVAE" if w == "cvae" else w for w in base.split("_") if w)
    words = words[:1].upper() + words[1:]
    return f"{words} + post-optimization" if post else words


def split_label(split: str) -> str:
    return SPLIT_LABELS.get(str(split), str(split))


def rung_label(rung: str) -> str:
    return RUNG_LABELS.get(str(rung), str(rung))


def percent_text(fraction) -> str:
    """A fraction as a percentage with one decimal ("17.5%"); "not run" for NaN or None."""
    try:
        value = float(fraction)
    except (TypeError, ValueError):
        return "not run"
    return f"{100 * value:.1f}%" if math.isfinite(value) else "not run"


def interval_text(low, high) -> str:
    """A 95% interval of fractions as whole percentages ("43–66"); empty when either end is missing."""
    try:
        low, high = float(low), float(high)
    except (TypeError, ValueError):
        return ""
    if not (math.isfinite(low) and math.isfinite(high)):
        return ""
    return f"{100 * low:.0f}–{100 * high:.0f}"


def seconds_text(seconds) -> str:
    """Seconds per grasp for a table cell: "0.35 s", "21 ms", "—" when unknown."""
    try:
        value = float(seconds)
    except (TypeError, ValueError):
        return "—"
    if not math.isfinite(value):
        return "—"
    if value < 0.1:
        return f"{1000 * value:.2g} ms" if value * 1000 < 10 else f"{1000 * value:.0f} ms"
    return f"{value:.2g} s" if value < 10 else f"{value:.0f} s"
