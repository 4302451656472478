"""A finished run's data stages as one dataset batch: its lift-tested grasps, its objects and what they cost.

A campaign batch is a workflow run of the data stages (prepare -> stability -> optimize -> curate -> lift-validate)
on a range of objects; ``run_batch`` reads what it made — ``results/lift/shard_*.zarr`` (every curated grasp with
its lift and six-direction outcome), ``results/optimized`` (which objects were optimized), the object catalog, the
stability table (each object's resting pose) — and the rules' CPU times from ``logs/benchmarks``. A model-made
batch (``workflow/rules/model_batch.smk``) has ``results/model_batch/shard_*.zarr`` instead of the lift and
optimized shards: every grasp tested, each with its source (model or optimization), the objects in its attributes. A held-out object
prepared at a seeded yaw (``objects.heldout_yaw``) is left out, named with the reason in the batch's config record.
The batch's hand is the one its shards record (``dataset.hand``): its grasps' attributes carry it to ``add_batch``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dexlite_pipeline.dataset.layout import OPTIONAL_ARRAYS, REQUIRED_ARRAYS
from dexlite_pipeline.dataset.validation import DatasetError
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store

# Snakemake rule -> the batches.csv cpu_seconds key (the data stages and what they need).
ENERGY_ARRAYS = ("E_fc", "E_dis", "E_pen", "E_spen", "E_joints", "E_table")
STAGE_RULES = ("prepare_objects", "stability_filter", "optimize_grasps", "curate", "lift_validate", "model_batch")
MODEL_BATCH_DIR = "model_batch"  # results/model_batch: a model-made batch's shards


@dataclass
class RunBatch:
    """One run's grasps (the dataset's arrays), its objects (objects.csv rows), CPU-s per stage and the stages' config."""

    grasps: GraspSet
    objects: object  # pandas.DataFrame
    cpu_seconds: dict[str, float]
    config: dict
    protocol: str
    shards: list[Path]  # the stores read: the run's last outputs (the batch's finish time)
    model_made: bool  # results/model_batch (kind model): each grasp's source is its own


def _stores(folder: Path, what: str) -> list[GraspSet]:
    paths = sorted(folder.glob("shard_*.zarr"))
    if not paths:
        raise DatasetError(f"{folder}: no shard_*.zarr ({what}); run the data stages first")
    return [read_grasp_store(p) for p in paths]


def lift_protocol(lift_config: dict) -> str:
    """One sentence of the test a held grasp passed, from the lift stage's recorded settings."""
    six = (f"; six directions: {lift_config['six_dir_force_per_kg_n']:g} N/kg for {lift_config['six_dir_duration_s']:g} s along ±x, ±y, ±z, "
           f"less than {100 * lift_config['six_dir_max_translation_m']:g} cm and {lift_config['six_dir_max_rotation_deg']:g}°"
           if lift_config.get("six_directions") else "")
    return (f"held: MuJoCo lift test on the object's table, the hand starting at most {1000 * lift_config['max_initial_penetration_m']:g} mm "
            f"inside the object, lifted {lift_config['lift_height_m']:g} m keeping {100 * lift_config['success_lift_ratio']:g}% of the rise "
            f"(object {lift_config['object_mass_kg']:g} kg, friction {lift_config['friction']:g}){six}")


def stage_cpu_seconds(logs: Path) -> dict[str, float]:
    """Rule -> CPU-s summed over its jobs (snakemake's benchmark files); rules without a file are left out."""
    import pandas as pd

    seconds = {}
    for rule in STAGE_RULES:
        files = sorted(logs.glob(f"{rule}.tsv")) + sorted(logs.glob(f"{rule}_[0-9]*.tsv"))
        if files:
            seconds[rule] = round(float(sum(pd.read_csv(f, sep="\t")["cpu_time"].iloc[0] for f in files)), 1)
    return seconds


def run_batch(results: str | Path, logs: str | Path | None = None) -> RunBatch:
    """The batch a run's ``results`` folder holds (``logs``: its ``logs/benchmarks``, default beside ``results``)."""
    import pandas as pd

    from dexlite_pipeline.objects.assets import load_asset

    results = Path(results)
    logs = Path(logs) if logs is not None else results.parent / "logs" / "benchmarks"
    model_made = (results / MODEL_BATCH_DIR).is_dir()
    if model_made:  # every grasp tested, its source its own; the objects and the sections in the shards' attributes
        made = _stores(results / MODEL_BATCH_DIR, "model-made grasps")
        lifted = GraspSet.concatenate([s for s in made if len(s)]) if any(len(s) for s in made) else made[0]
        shards = sorted((results / MODEL_BATCH_DIR).glob("shard_*.zarr"))
    else:
        lifted = GraspSet.concatenate(_stores(results / "lift", "lift-validated grasps"))
        made = _stores(results / "optimized", "optimized grasps")  # which objects were optimized (with or without a held grasp)
        shards = sorted((results / "lift").glob("shard_*.zarr"))
    if len(lifted) and "six_dir_success" not in lifted.arrays:
        raise DatasetError(f"{shards[0].parent}: no six_dir_success; a dataset batch needs the six-direction test (lift.six_directions: true)")
    arrays = {name: lifted.arrays[name] for name in (*REQUIRED_ARRAYS, *OPTIONAL_ARRAYS) if name in lifted.arrays}
    for name in ENERGY_ARRAYS:  # a term the run did not compute (E_table when floating) is NaN, as the schema says
        arrays.setdefault(name, np.full(len(lifted), np.nan, np.float32))
    # What made each grasp: the model batch's own record, else curation's origin (optimization from scratch, or a
    # DexGraspNet import), else optimization.
    if not model_made:
        arrays["source"] = np.asarray([str(o) or "optimization" for o in lifted.arrays.get("origin", np.full(len(lifted), "", dtype=object))],
                                      dtype=object)
    # The hand the shards record (one hand, else refused in one line): the batch's (dataset.hand; {} for the Shadow Hand).
    from dexlite_pipeline.dataset.hand import hand_attrs
    from dexlite_pipeline.io.grasp_store import GraspStoreError, check_one_hand

    try:
        hand = hand_attrs(check_one_hand([(str(p), read_grasp_store(p).attrs) for p in shards]))
    except GraspStoreError as exc:
        raise DatasetError(str(exc)) from None
    grasps = GraspSet(arrays, hand)
    # Every object optimized (with or without a held grasp) and every object with a tested grasp (an import's too).
    object_ids = sorted({o for store in made for o in store.attrs.get("objects", [])} | {str(o) for o in grasps.object_id})
    objects_dirs = [d for d in (results / "objects", results / "dexgraspnet" / "objects") if (d / "catalog.parquet").is_file()]
    catalog = pd.concat([pd.read_parquet(d / "catalog.parquet") for d in objects_dirs]).drop_duplicates("object_id").set_index("object_id")
    stability = pd.read_parquet(results / "stability" / "stability.parquet").set_index("object_id")
    rows, left_out = [], {}
    for object_id in object_ids:
        if object_id not in catalog.index:
            raise DatasetError(f"{results}: object {object_id} is in no catalog of {', '.join(str(d) for d in objects_dirs)}")
        meta = load_asset([str(d) for d in objects_dirs], object_id).meta
        if meta.get("turned_about_z_deg"):
            left_out[object_id] = (f"prepared turned {meta['turned_about_z_deg']:.1f} deg about z (a held-out object at its seeded "
                                   "yaw, objects.heldout_yaw): the dataset's objects are rebuilt unturned, which its grasps would not fit")
            continue
        row = {"object_id": object_id, "source": str(catalog.at[object_id, "source"]), "split": str(catalog.at[object_id, "split"]),
               "real_radius_m": meta.get("real_radius_m") if meta.get("real_radius_m") is not None else np.nan}
        for column in ("support_nx", "support_ny", "support_nz", "support_offset", "rest_qx", "rest_qy", "rest_qz", "rest_qw"):
            if column in stability.columns and object_id in stability.index:
                row[column] = float(stability.at[object_id, column])
        rows.append(row)
    lift_attrs = lifted.attrs if len(lifted) else read_grasp_store(shards[0]).attrs
    if model_made:
        config = {**made[0].attrs.get("config", {}), "lift": lift_attrs.get("lift_config", {}),
                  **{k: made[0].attrs.get(k) for k in ("model_file", "model_sha256", "evaluator_file", "evaluator_sha256")},
                  "topped_up_objects": sorted(o for store in made for o in store.attrs.get("topped_up_objects", []))}
    else:
        config = {"optimize_grasps": made[0].attrs.get("config", {}), "lift": lift_attrs.get("lift_config", {}),
                  "curate": lift_attrs.get("config", {}).get("curate", {})}
    config = json.loads(json.dumps(config, default=str))
    if left_out:
        config["left_out_objects"] = left_out  # the batch's config record keeps them, with the reason (dataset-add prints them)
        grasps = GraspSet(grasps.select(np.flatnonzero(~np.isin(grasps.object_id.astype(str), sorted(left_out)))).arrays, grasps.attrs)
    return RunBatch(grasps, pd.DataFrame(rows), stage_cpu_seconds(logs), config, lift_protocol(lift_attrs.get("lift_config", {})), shards,
                    model_made)
