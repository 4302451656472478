"""``dexlite import-dexgraspnet ROOT --out GRASPS.zarr --objects-out DIR``: import a DexGraspNet download.

Writes the grasp store (``object_id`` = object code, ``scale``, ``source_file``,
``source_index``), one object asset per imported object under ``DIR/assets/`` with the
catalog ``DIR/catalog.parquet``, and an import report CSV listing every file or grasp
that was not imported, with a reason. Config (``--config-json``, sections ``seed``,
``objects`` and ``dexgraspnet``): the ``objects`` keys set the SDF grid and surface
samples (keep them equal to the pipeline's so grids match), ``dexgraspnet`` the split.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
from pathlib import Path

log = logging.getLogger(__name__)

# The keys of config section ``objects`` the import uses (its meshes bring their own pieces).
ASSET_CONFIG_KEYS = ("sdf_resolution", "sdf_padding", "surface_points")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("root", help="DexGraspNet download (with dataset/ and meshdata/)")
    parser.add_argument("--out", required=True, help="output grasp store (.zarr)")
    parser.add_argument("--objects-out", required=True, help="output objects dir (assets/ and catalog.parquet)")
    parser.add_argument("--report", default=None, help="import report CSV (default: next to --out, <name>.import_report.csv)")
    parser.add_argument("--config-json", default="{}", help="config sections seed, objects, dexgraspnet as JSON (defaults otherwise)")


def asset_settings(config: dict):
    """Asset build settings from ``ASSET_CONFIG_KEYS`` of the ``objects`` section and ``seed``."""
    from dexlite_pipeline.objects.build import AssetBuildSettings

    objects = config.get("objects") or {}
    return AssetBuildSettings(**{k: objects[k] for k in ASSET_CONFIG_KEYS if k in objects}, seed=int(config.get("seed", 0)))


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.config import from_section, parse_config_json
    from dexlite_pipeline.io.dexgraspnet import (
        CATALOG_COLUMNS,
        REPORT_COLUMNS,
        UNKNOWN_GRASP_COUNT,
        DexGraspNetConfig,
        import_dexgraspnet,
        problem_rows,
        write_table_atomic,
    )
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.objects.assets import CATALOG_NAME

    config = parse_config_json(args.config_json)
    section = from_section(DexGraspNetConfig, config.get("dexgraspnet"), "config.dexgraspnet")
    settings = asset_settings(config)
    seed = int(config.get("seed", 0))
    out = Path(args.out)
    report = Path(args.report) if args.report else out.with_name(f"{out.stem}.import_report.csv")

    result = import_dexgraspnet(args.root, args.objects_out, settings, section, seed, workers=args.threads or 1)
    write_table_atomic(result.catalog, CATALOG_COLUMNS, Path(args.objects_out) / CATALOG_NAME)
    write_table_atomic(problem_rows(result.problems), REPORT_COLUMNS, report)
    ok_objects = sum(row["status"] == "ok" for row in result.catalog)
    rejected_grasps = sum(p.grasps_affected for p in result.problems if p.grasps_affected != UNKNOWN_GRASP_COUNT)
    files_not_read = sum(p.grasp_index == -1 and p.grasps_affected == 0 for p in result.problems)
    files_uncounted = sum(p.grasps_affected == UNKNOWN_GRASP_COUNT for p in result.problems)
    attrs = {
        "stage": "import_dexgraspnet",
        "source": "dexgraspnet",
        "source_root": str(Path(args.root).resolve()),
        "config": {"seed": seed, "dexgraspnet": dataclasses.asdict(section), "asset_settings": dataclasses.asdict(settings)},
        "objects_imported": ok_objects,
        "grasps_imported": len(result.grasps),
        "grasps_not_imported": rejected_grasps,
        "files_not_read": files_not_read,
        "failed_files_with_unknown_grasp_count": files_uncounted,
    }
    write_grasp_store(out, result.grasps, attrs)
    uncounted = f" (plus the grasps of {files_uncounted} failed files, number unknown)" if files_uncounted else ""
    print(
        f"imported {len(result.grasps)} grasps of {ok_objects}/{len(result.catalog)} objects; "
        f"{rejected_grasps} grasps{uncounted} and {files_not_read} whole files not imported, {len(result.problems)} problems (see {report})"
    )
    return 0
