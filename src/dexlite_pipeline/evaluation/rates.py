"""Success rates of a set of grasps with 95% intervals, on plain numpy arrays.

Rates are fractions in [0, 1]; NaN when there is nothing to measure (never 0 by default). A
rate of per-grasp successes comes with a 95% Wilson score interval: with 80 grasps a rate of 20%
is 12–30%, so a difference of a few points between methods is not a finding. Wilson treats the
grasps as independent, but they come in clusters (16 each from 5 objects) and grasps of one
object succeed or fail together, so rates also get an object-level (cluster) bootstrap 95%
interval: objects resampled with replacement. It is wider than Wilson's when success depends
strongly on the object (two of five objects always hold, three never: 0–80% against Wilson's
30–51%); with as few as 5 objects it is itself rough (it sees only the spread the sampled
objects show) and can come out narrower, so read the two together.
"""

from __future__ import annotations

import math

import numpy as np

BOOTSTRAP_RESAMPLES = 4000  # resamples of the object bootstrap


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
