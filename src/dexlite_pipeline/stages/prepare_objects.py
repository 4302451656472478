"""``dexlite prepare-objects --catalog results/objects/catalog.parquet --record ...``: build every object asset.

Config sections ``seed`` and ``objects``. Writes ``assets/<id>/`` beside the catalog per
usable object (and the generated household meshes, in metres, to ``household_meshes/``),
the catalog (every object, ok or rejected with the reason, with its split) and the record
of the config used. A configured folder that does not exist stops the run at
once; a bad mesh is only a rejected row, but a run in which every object is rejected exits
with status 1.
"""

from __future__ import annotations

import argparse
import logging
import os
import time

log = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", default="{}", help="config sections seed and objects as JSON (defaults otherwise)")
    parser.add_argument("--catalog", required=True, help="output catalog (DIR/catalog.parquet; the assets go to DIR/assets/)")
    parser.add_argument("--record", required=True, help="output record of the settings used (.json)")
    parser.add_argument("--dataset", default="", help="the grasp dataset folder whose objects objects.dataset_objects adds")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from dexlite_pipeline.objects.prepare import prepare_objects
    from dexlite_pipeline.objects.sources import HOUSEHOLD_MESH_DIR, collect_sources
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    section = config.objects
    try:
        rebuilt = dataset_training_ids(args.dataset) if section.dataset_objects else ()
        rests = dataset_rest_poses(args.dataset, rebuilt) if section.dataset_objects and not section.dataset_collision else None
    except ValueError as error:
        log.error("%s", error)
        return 2
    sources = collect_sources(
        section.builtin_count, section.mesh_dirs, section.heldout_mesh_dirs, config.seed, section.benchmark_heldout, section.benchmark_objects,
        section.household_count, section.household_benchmark_objects, Path(args.catalog).parent / HOUSEHOLD_MESH_DIR, section.household_first,
        section.household_families, section.household_variants, section.shapes_benchmark_objects, rebuilt,
        section.procedural_count, section.procedural_first, rests,
    )
    workers = args.threads or os.cpu_count() or 1
    log.info("preparing %d objects with %d worker(s)", len(sources), workers)
    start = time.perf_counter()
    catalog = prepare_objects(sources, Path(args.catalog).parent, section, config.seed, workers, args.catalog, args.record)
    ok = catalog["status"] == "ok"
    for row in catalog[~ok].itertuples():
        log.warning("rejected %s (%s): %s", row.object_id, row.file, row.reason)
    counts = catalog.loc[ok, "split"].value_counts()
    print(
        f"prepared {int(ok.sum())}/{len(catalog)} objects ({counts.get('train', 0)} train, {counts.get('heldout', 0)} heldout, "
        f"{int((~ok).sum())} rejected) in {time.perf_counter() - start:.1f} s -> {args.catalog}"
    )
    if len(catalog) and not ok.any():
        log.error("none of the %d objects could be prepared (reasons above)", len(catalog))
        return 1
    return 0


def dataset_training_ids(dataset_dir: str) -> tuple[str, ...]:
    """The training objects of the grasp dataset at ``dataset_dir``, in its objects.csv order (objects.dataset_objects)."""
    from pathlib import Path

    from dexlite_pipeline.dataset.store import read_objects

    if not dataset_dir:
        raise ValueError("objects.dataset_objects: no grasp dataset given (dataset.root is empty)")
    if not (Path(dataset_dir) / "batches.csv").is_file():
        raise ValueError(f"objects.dataset_objects: {dataset_dir} is not a grasp dataset (no batches.csv)")
    objects = read_objects(dataset_dir)
    training = objects[objects["split"] == "train"]
    log.info("the dataset %s: %d training objects of %d", dataset_dir, len(training), len(objects))
    return tuple(str(o) for o in training["object_id"])


def dataset_rest_poses(dataset_dir: str, object_ids) -> dict:
    """The resting pose the dataset at ``dataset_dir`` records for each of ``object_ids`` (its first row of objects.csv), by id
    (``objects.rest_pose.RecordedRest``); an object recorded without one (a batch made without a table) is prepared and
    simulated as usual, said once in the log (objects.dataset_collision false)."""
    from dexlite_pipeline.dataset.store import read_objects
    from dexlite_pipeline.objects.rest_pose import RecordedRest

    objects = read_objects(dataset_dir).drop_duplicates("object_id", keep="first").set_index("object_id")
    rests = {}
    for object_id in object_ids:
        rest = RecordedRest.from_row(objects.loc[object_id]) if object_id in objects.index else None
        if rest is not None:
            rests[object_id] = rest
    missing = len(set(object_ids)) - len(rests)
    log.info("objects.dataset_collision false: %d dataset objects stand in their recorded resting pose, without collision pieces; "
             "%d without a recorded pose are prepared in full", len(rests), missing)
    return rests
