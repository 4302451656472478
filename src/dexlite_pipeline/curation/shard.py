"""Curating one shard: the ``curate`` stage's work.

Reads the shard's optimized grasps (with their energy terms) and, optionally, the imported
DexGraspNet grasps of the shard's objects (their energies are computed here); keeps the
grasps ``curation.filters`` admits; returns the curated grasps (``origin`` optimization/dexgraspnet
and ``origin_index``, the row in its input), their store attributes and a per-object summary
of kept and dropped counts. Grasps whose force closure could not be computed (an unreadable
object asset) are dropped as ``force_closure_unknown`` and counted by reason.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from dexlite_pipeline.curation.filters import (
    DROP_REASONS,
    TABLETOP_DROP_REASONS,
    ObjectFacts,
    curate_grasps,
    merge_summaries,
    object_reasons,
    summarize,
)
from dexlite_pipeline.curation.config import IMPORTED_ORIGIN, CurateConfig
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store

if TYPE_CHECKING:
    from dexlite_pipeline.energy.config import EnergyConfig
    from dexlite_pipeline.sim.config import SceneConfig

log = logging.getLogger(__name__)

OPTIMIZED_ORIGIN = "optimization"  # ``origin`` of grasps from optimization from scratch
# Fill values of energy arrays for imported grasps dropped before their energies are computed.
NOT_EVALUATED = {"f": np.nan, "i": -1, "b": False, "O": ""}


def tag_origin(grasps: GraspSet, origin: str) -> GraspSet:
    """``grasps`` with ``origin`` (where they come from) and ``origin_index`` (their row there)."""
    grasps.arrays["origin"] = np.full(len(grasps), origin, dtype=object)
    grasps.arrays["origin_index"] = np.arange(len(grasps), dtype=np.int64)
    return grasps


def imported_with_energies(
    imported_path: str, objects_dirs: list[str], shard: int, shards: int, facts: ObjectFacts, energy: EnergyConfig, batch_size: int, device: str
) -> GraspSet:
    """This shard's (of ``shards``) imported grasps, with energies (``energy``, ``batch_size`` grasps at a time) for those that pass the object checks."""
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.energy.per_grasp import evaluate_grasp_energies
    from dexlite_pipeline.sharding import shard_objects

    imported = tag_origin(read_grasp_store(imported_path), IMPORTED_ORIGIN)
    ids = np.asarray([str(o) for o in imported.object_id])
    imported = imported.select(np.isin(ids, shard_objects(ids, shard, shards)))
    candidates = object_reasons(imported, facts) == ""
    log.info("imported grasps of shard %d: %d, energies computed for %d", shard, len(imported), int(candidates.sum()))
    energies = evaluate_grasp_energies(
        imported.select(candidates), objects_dirs, device=resolve_device(device), batch_size=batch_size, config=energy,
    )
    for name, values in energies.items():
        full = np.full((len(imported), *values.shape[1:]), NOT_EVALUATED[values.dtype.kind], dtype=values.dtype)
        full[candidates] = values
        imported.arrays[name] = full
    return imported


def _common_arrays(sets: list[GraspSet]) -> GraspSet:
    """Concatenate sets keeping the arrays all of them with rows have (provenance arrays always exist)."""
    grasps, left_out = GraspSet.concatenate_common(sets)
    if left_out:
        log.info("arrays not present in every input, left out of the curated store: %s", ", ".join(left_out))
    return grasps


def force_closure_evaluator(objects_dirs: list[str], settings: CurateConfig, threads: int, hand=None):
    """grasps -> Ferrari–Canny ε of their actual contacts (``ForceClosureResult``), with the contact model of ``settings``,
    the links of ``hand`` (None: the Shadow Hand)."""
    from dexlite_pipeline.curation.force_closure import ContactModel, evaluate_force_closure

    model = ContactModel(
        contact_distance_m=settings.force_closure_contact_distance_m,
        friction=settings.force_closure_friction,
        cone_edges=settings.force_closure_cone_edges,
    )

    def evaluate(grasps):
        result = evaluate_force_closure(grasps, objects_dirs, model, hand=hand, threads=threads)
        epsilon = result.epsilon[np.isfinite(result.epsilon)]
        log.info(
            "force closure of %d grasps: %d evaluated, epsilon median %.4f, %.1f%% above %g",
            len(grasps), len(epsilon), float(np.median(epsilon)) if len(epsilon) else math.nan,
            100 * float((epsilon > settings.force_closure_min_epsilon).mean()) if len(epsilon) else 0.0, settings.force_closure_min_epsilon,
        )
        return result

    return evaluate


def curate_shard(
    optimized_paths: list[str], imported_path: str | None, stability_paths: list[str], objects_dirs: list[str],
    shard: int, *, shards: int, curate: CurateConfig, energy: EnergyConfig, scene: SceneConfig, device: str, threads: int = 1,
    hand: str = "shadow",
) -> tuple[GraspSet, dict, pd.DataFrame]:
    """The curated grasps of one shard, their store attributes and the per-object summary.

    The config it reads comes as arguments: ``shards``, ``device``, sections ``curate``, ``scene`` and (for imported grasps) ``energy``.
    In tabletop mode (``scene.table``) every grasp, optimized or imported, with a hand point below its
    object's table (the first stability table's resting pose) is dropped as ``below_table``.

    ``hand`` (config key ``hand``): every input store must be of this hand (a store without ``hand`` is the Shadow
    Hand's, as DexGraspNet imports are), else ``GraspStoreError`` in one line naming both; the table depth, the
    near-duplicate test and the force-closure check use its links and joints, and the curated store records it.
    """
    from dexlite_pipeline.config import json_ready
    from dexlite_pipeline.hand.choice import hand_record, resolve_hand
    from dexlite_pipeline.io.grasp_store import check_one_hand
    from dexlite_pipeline.objects.assets import CATALOG_NAME, read_catalog
    from dexlite_pipeline.objects.stability import read_stability_table

    settings = curate
    catalogs = [read_catalog(d) for d in objects_dirs if (Path(d) / CATALOG_NAME).exists()]
    facts = ObjectFacts.from_tables(catalogs, [read_stability_table(p) for p in stability_paths])
    sets = [tag_origin(read_grasp_store(p), OPTIMIZED_ORIGIN) for p in optimized_paths]
    if imported_path:
        sets.append(imported_with_energies(imported_path, objects_dirs, shard, shards, facts, energy, settings.energy_batch_size, device))
    if not sets:
        raise ValueError("curate needs optimized grasps and/or imported grasps")
    inputs = [*optimized_paths, *([imported_path] if imported_path else [])]
    record = check_one_hand([(f"config key hand ({hand})", hand_record(hand)), *((str(p), s.attrs) for p, s in zip(inputs, sets))])
    hand_model = resolve_hand(hand, "cpu")
    grasps = _common_arrays(sets)
    table_depth = None
    if scene.table:
        from dexlite_pipeline.energy.table_clearance import grasp_table_depths
        from dexlite_pipeline.tabletop import load_support_planes

        table_depth = grasp_table_depths(grasps, load_support_planes(True, stability_paths[0]), hand=hand_model)
    drop_reasons = TABLETOP_DROP_REASONS if scene.table else DROP_REASONS
    reasons = curate_grasps(grasps, facts, settings, force_closure_evaluator(objects_dirs, settings, threads, hand_model), table_depth_m=table_depth)
    # Reported in the attributes and the log, not stored: it is '' for every kept grasp.
    failure_reason = grasps.arrays.pop("force_closure_failure_reason", np.full(len(grasps), "", dtype=object))
    force_closure_failures = Counter(failure_reason[failure_reason != ""].tolist())
    kept = grasps.select(reasons == "")
    attrs = {
        "stage": "curate",
        "shard": shard,
        **record,
        "config": {"curate": json_ready(settings), "energy": json_ready(energy) if imported_path else None},
        "inputs": {"optimized": list(optimized_paths), "imported": imported_path, "stability": list(stability_paths)},
        "n_input": len(grasps),
        "n_kept": len(kept),
        "dropped": {r: int((reasons == r).sum()) for r in drop_reasons},
        "force_closure_failures": dict(force_closure_failures),
    }
    if scene.table:
        attrs["config"]["scene"] = {"table": True}
        attrs["scene"] = {"table": True}
    return kept, attrs, summarize(grasps, reasons, facts, drop_reasons)


def merge_summary_files(paths: list[str]) -> pd.DataFrame:
    """The per-shard summary CSVs as one per-object table."""
    return merge_summaries([pd.read_csv(p, keep_default_na=False) for p in paths])
