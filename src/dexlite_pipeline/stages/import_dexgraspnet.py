"""``dexlite import-dexgraspnet ROOT --out GRASPS.zarr --catalog DIR/catalog.parquet --report R.csv``: import a DexGraspNet download.

Writes the grasp store (``object_id`` = object code, ``scale``, ``source_file``,
``source_index``), one object asset per imported object under ``DIR/assets/`` with the
catalog, and an import report CSV listing every file or grasp that was not imported, with a
reason (``io.dexgraspnet.import_download``). Config (``--config-json``, sections ``seed``,
``objects`` and ``dexgraspnet``): the ``objects`` keys set the SDF grid and surface samples
(keep them equal to the pipeline's so grids match), ``dexgraspnet`` the split.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("root", help="DexGraspNet download (with dataset/ and meshdata/)")
    parser.add_argument("--out", required=True, help="output grasp store (.zarr)")
    parser.add_argument("--catalog", required=True, help="output object catalog (DIR/catalog.parquet; the assets go to DIR/assets/)")
    parser.add_argument("--report", required=True, help="output import report (.csv)")
    parser.add_argument("--config-json", default="{}", help="config sections seed, objects, dexgraspnet as JSON (defaults otherwise)")


def run(args: argparse.Namespace) -> int:
    import dataclasses

    from dexlite_pipeline.io.dexgraspnet import import_download
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    counts = import_download(args.root, args.out, args.catalog, args.report, config.seed, dataclasses.asdict(config.objects),
                             config.dexgraspnet, workers=args.threads or 1)
    unknown = counts["failed_files_with_unknown_grasp_count"]
    uncounted = f" (plus the grasps of {unknown} failed files, number unknown)" if unknown else ""
    print(
        f"imported {counts['grasps_imported']} grasps of {counts['objects_imported']}/{counts['objects']} objects; "
        f"{counts['grasps_not_imported']} grasps{uncounted} and {counts['files_not_read']} whole files not imported, "
        f"{counts['problems']} problems (see {args.report})"
    )
    return 0
