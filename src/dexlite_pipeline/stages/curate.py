"""``dexlite curate``: filter seed (and imported DexGraspNet) grasps into training data.

Two steps, so that each shard is one job and the summary one small job:

- ``--step curate --shard K``: reads the seed shard (grasps with E_* arrays) and, with
  ``--imported``, the imported DexGraspNet grasps of this shard's objects (their energies
  are computed here); keeps the grasps ``dexlite_pipeline.curate`` admits; writes the
  curated store (``origin`` seed/dexgraspnet and ``origin_index``, the row in its input)
  and a per-object summary CSV of kept and dropped counts. Grasps whose force closure
  could not be computed (an unreadable object asset) are dropped as
  ``force_closure_unknown``; their reasons are printed and counted in the store's
  attribute ``force_closure_failures``.
- ``--step aggregate``: merges the per-shard summaries into one CSV.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import math
from collections import Counter
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

# Fill values of energy arrays for imported grasps dropped before their energies are computed.
NOT_EVALUATED = {"f": np.nan, "i": -1, "b": False, "O": ""}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--step", choices=("curate", "aggregate"), required=True)
    parser.add_argument("--config-json", default="{}", help="config sections (seed, device, shards, curate, energy) as JSON")
    parser.add_argument("--shard", type=int, default=None, help="curate: shard index (selects the imported objects of this shard)")
    parser.add_argument("--seed-grasps", action="append", default=[], help="curate: seed grasp store(s) of this shard (repeatable)")
    parser.add_argument("--imported", default=None, help="curate: imported DexGraspNet grasp store (all objects; this shard's are used)")
    parser.add_argument("--stability", action="append", default=[], help="curate: stability table(s) (.parquet, repeatable)")
    parser.add_argument("--objects", action="append", default=[], help="curate: prepared objects dir(s) with catalogs (repeatable)")
    parser.add_argument("--out", help="curate: curated grasp store; aggregate: merged summary CSV")
    parser.add_argument("--summary-out", help="curate: this shard's summary CSV")
    parser.add_argument("--summary", action="append", default=[], help="aggregate: per-shard summary CSVs")


def _tag(grasps, origin: str):
    grasps.arrays["origin"] = np.full(len(grasps), origin, dtype=object)
    grasps.arrays["origin_index"] = np.arange(len(grasps), dtype=np.int64)
    return grasps


def _imported_with_energies(args, config: dict, curate_config, facts):
    """This shard's imported grasps, with energies for those that pass the object checks."""
    from dexlite_pipeline.config import from_section
    from dexlite_pipeline.curate import IMPORTED_ORIGIN, object_reasons
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.energy import EnergyConfig, evaluate_grasp_energies
    from dexlite_pipeline.io.grasp_store import read_grasp_store
    from dexlite_pipeline.sharding import shard_objects

    imported = _tag(read_grasp_store(args.imported), IMPORTED_ORIGIN)
    ids = np.asarray([str(o) for o in imported.object_id])
    mine = shard_objects(ids, args.shard, int(config.get("shards", 1)))
    imported = imported.select(np.isin(ids, mine))
    energy_config = from_section(EnergyConfig, config.get("energy"), "config.energy")
    candidates = object_reasons(imported, facts) == ""
    log.info("imported grasps of shard %d: %d, energies computed for %d", args.shard, len(imported), int(candidates.sum()))
    energies = evaluate_grasp_energies(
        imported.select(candidates),
        args.objects,
        device=resolve_device(config.get("device", "auto")),
        batch_size=curate_config.energy_batch_size,
        config=energy_config,
    )
    for name, values in energies.items():
        full = np.full((len(imported), *values.shape[1:]), NOT_EVALUATED[values.dtype.kind], dtype=values.dtype)
        full[candidates] = values
        imported.arrays[name] = full
    return imported


def _common_arrays(sets):
    """Concatenate sets keeping the arrays all of them with rows have (provenance arrays always exist)."""
    from dexlite_pipeline.io.grasp_store import GraspSet

    grasps, left_out = GraspSet.concatenate_common(sets)
    if left_out:
        log.info("arrays not present in every input, left out of the curated store: %s", ", ".join(left_out))
    return grasps


def _force_closure_evaluator(objects_dirs, curate_config, threads: int):
    """grasps -> Ferrari–Canny ε of their actual contacts (``ForceClosureResult``), with the contact model of ``curate_config``, on ``threads`` threads."""
    from dexlite_pipeline.force_closure import ContactModel, evaluate_force_closure

    model = ContactModel(
        contact_distance_m=curate_config.force_closure_contact_distance_m,
        friction=curate_config.force_closure_friction,
        cone_edges=curate_config.force_closure_cone_edges,
    )

    def evaluate(grasps):
        result = evaluate_force_closure(grasps, objects_dirs, model, threads=threads)
        epsilon = result.epsilon[np.isfinite(result.epsilon)]
        log.info(
            "force closure of %d grasps: %d evaluated, epsilon median %.4f, %.1f%% above %g",
            len(grasps), len(epsilon), float(np.median(epsilon)) if len(epsilon) else math.nan,
            100 * float((epsilon > curate_config.force_closure_min_epsilon).mean()) if len(epsilon) else 0.0, curate_config.force_closure_min_epsilon,
        )
        return result

    return evaluate


def _curate_shard(args, config: dict) -> int:
    from dexlite_pipeline.config import from_section
    from dexlite_pipeline.curate import DROP_REASONS, CurateConfig, ObjectFacts, curate_grasps, summarize
    from dexlite_pipeline.io.atomic import atomic_path
    from dexlite_pipeline.io.grasp_store import read_grasp_store, write_grasp_store
    from dexlite_pipeline.objects.assets import CATALOG_NAME, read_catalog
    from dexlite_pipeline.objects.stability import read_stability_table

    if args.shard is None or not args.out or not args.summary_out:
        raise ValueError("--step curate needs --shard, --out and --summary-out")
    curate_config = from_section(CurateConfig, config.get("curate"), "config.curate")
    catalogs = [read_catalog(d) for d in args.objects if (Path(d) / CATALOG_NAME).exists()]
    stability = [read_stability_table(p) for p in args.stability]
    facts = ObjectFacts.from_tables(catalogs, stability)
    sets = [_tag(read_grasp_store(p), "seed") for p in args.seed_grasps]
    if args.imported:
        sets.append(_imported_with_energies(args, config, curate_config, facts))
    if not sets:
        raise ValueError("--step curate needs --seed-grasps and/or --imported")
    grasps = _common_arrays(sets)
    reasons = curate_grasps(grasps, facts, curate_config, _force_closure_evaluator(args.objects, curate_config, args.threads or 1))
    # Reported in the attributes and printed, not stored: it is '' for every kept grasp.
    failure_reason = grasps.arrays.pop("force_closure_failure_reason", np.full(len(grasps), "", dtype=object))
    force_closure_failures = Counter(failure_reason[failure_reason != ""].tolist())
    kept = grasps.select(reasons == "")
    counts = {r: int((reasons == r).sum()) for r in DROP_REASONS}
    attrs = {
        "stage": "curate",
        "shard": args.shard,
        "config": {"curate": dataclasses.asdict(curate_config), "energy": config.get("energy")},
        "inputs": {"seed": list(args.seed_grasps), "imported": args.imported, "stability": list(args.stability)},
        "n_input": len(grasps),
        "n_kept": len(kept),
        "dropped": counts,
        "force_closure_failures": dict(force_closure_failures),
    }
    write_grasp_store(args.out, kept, attrs)
    with atomic_path(args.summary_out) as tmp:
        summarize(grasps, reasons, facts).to_csv(tmp, index=False)
    dropped = ", ".join(f"{r} {c}" for r, c in counts.items() if c)
    print(f"shard {args.shard}: kept {len(kept)} of {len(grasps)} grasps; dropped: {dropped or 'none'}")
    for reason, count in force_closure_failures.items():
        print(f"shard {args.shard}: {count} grasps dropped as force_closure_unknown: {reason}")
    return 0


def _aggregate(args) -> int:
    import pandas as pd

    from dexlite_pipeline.curate import merge_summaries
    from dexlite_pipeline.io.atomic import atomic_path

    if not args.summary or not args.out:
        raise ValueError("--step aggregate needs --summary (one per shard) and --out")
    merged = merge_summaries([pd.read_csv(p, keep_default_na=False) for p in args.summary])
    with atomic_path(args.out) as tmp:
        merged.to_csv(tmp, index=False)
    print(f"curation summary: {int(merged['n_kept'].sum())} of {int(merged['n_input'].sum())} grasps kept over {len(merged)} objects")
    return 0


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.config import parse_config_json

    if args.step == "aggregate":
        return _aggregate(args)
    return _curate_shard(args, parse_config_json(args.config_json))
