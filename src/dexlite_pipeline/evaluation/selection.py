"""Which grasps each method is measured on: a seeded draw of at most ``grasps_per_object`` per (method, object).

The methods and their stores are listed in ``evaluation.protocol``. The CVAE methods and the
random-init baseline share one draw over the sampled rows, so they are compared on the same
source rows; a chosen grasp with an unusable pose or scale stays in as a failure. Also the seconds
per attempt of the stages that made a method's grasps (its cost columns).
"""

from __future__ import annotations

import hashlib
from collections import Counter
from collections.abc import Mapping, Sequence

import numpy as np

from dexlite_pipeline.evaluation.config import EvaluateConfig, draw_label
from dexlite_pipeline.io.grasp_store import GRASP_TYPE, GraspSet, grasp_types, invalid_grasp_reasons

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
    "cvae_ranked": ("cvae_ranked", "sample"),
    "cvae_ranked_post": ("cvae_ranked", "post"),
}
RANKED = ("cvae_ranked", "cvae_ranked_post")  # their sampling cost is the ranking's: a larger pool drawn and scored
PAIRED_METHODS = (*SAMPLED_METHODS, "random_post")  # rows correspond to rows of the sampled store
PAIRED_DRAW = "sampled_rows"  # name of the draw these methods share
SELECTED_ARRAYS = ("hand_pose", "object_id", "scale")
BUDGET_POSES = "budget_hand_pose"  # (N, S, 6 + J) post-optimized poses after each budget iteration (post stores)


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
    rank: np.ndarray | None = None,
) -> GraspSet:
    """The grasps of one method on objects of the evaluated splits, at most ``grasps_per_object`` per object.

    Per object, the rows with the lowest seeded priorities are taken. With ``sample_rows``
    (each grasp's row in the sampled store, see ``sample_rows_of``) the priorities are those
    of the sampled rows in one draw shared by the paired methods, so they take the same
    source rows; otherwise the method draws over its own rows. A grasp with an unusable
    pose or scale is chosen like any other and kept with its ``invalid_reason``: it is not
    simulated and counts as a failure. With ``rank`` (per grasp, lower first: the learned
    evaluator's ranking of ranked rows) the best-ranked are taken instead of a seeded draw, so a
    ranked method is measured on its best grasps, as a user would refine them. Adds ``method``, ``split``, ``source_row`` (row in
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
    if rank is not None:
        priority = np.asarray(rank, np.float64)
    chosen: list[int] = []
    for object_id in sorted(set(object_ids[candidate])):
        rows = np.flatnonzero(candidate & (object_ids == object_id))
        chosen.extend(sorted(rows[np.argsort(priority[rows], kind="stable")][: cfg.cap_of(method)].tolist()))
    rows = np.asarray(chosen, dtype=np.int64)
    arrays = {name: grasps.arrays[name][rows] for name in (*SELECTED_ARRAYS, BUDGET_POSES, GRASP_TYPE) if name in grasps.arrays}
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
    the thresholds too (the equal filter is applied later, to every method alike). Each grasp keeps its
    ``grasp_type`` (power where a store has none), which the report counts.
    """
    parts = []
    for source in sources:
        subset = source
        if method in SAMPLED_METHODS:
            subset = source.select(_labelled(source, SAMPLED_METHODS[method][0]))
        kept = (*SELECTED_ARRAYS, BUDGET_POSES) if all(BUDGET_POSES in src.arrays for src in sources) else SELECTED_ARRAYS
        parts.append(GraspSet({**{k: subset.arrays[k] for k in kept}, GRASP_TYPE: grasp_types(subset)}, subset.attrs))
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
    CPU-seconds (an upper bound when the core is shared). The ranked rows' sampling is the ranking's,
    which the simulate step adds (``shards.ranking_seconds_per_attempt``: drawing the whole pool and
    scoring it, over the ranked grasps it simulates). Not included: training (of the model and the evaluator), object
    preparation, the evaluation's energies (the filter) and its simulation. DexGraspNet's
    imported grasps carry no cost.
    """
    stages = {"optimization": ("optimized",), "random_post": ("random_post",), "dexgraspnet": ()}
    stages.update({m: ("sample",) if stage == "sample" else ("sample", "post") for m, (_, stage) in SAMPLED_METHODS.items()})
    stages.update({m: () if SAMPLED_METHODS[m][1] == "sample" else ("post",) for m in RANKED})
    out = {}
    for stage in stages[method]:
        sets = sources.get(stage, [])
        weighted = [(float(s.attrs["seconds_per_grasp"]), len(s)) for s in sets if s.attrs.get("seconds_per_grasp") is not None and len(s)]
        if weighted:
            total = sum(n for _, n in weighted)
            out[stage] = sum(t * n for t, n in weighted) / total
    return out
