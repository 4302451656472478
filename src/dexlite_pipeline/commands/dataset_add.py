"""``dexlite dataset-add RESULTS --dataset DIR``: add a finished run's data stages to a grasp dataset as one batch.

A campaign batch is a run of the data stages on a range of objects (``config/profiles/household_campaign.yaml``);
this command adds every lift-tested grasp of it (held or not, with its energies and outcomes), its objects (with
their resting poses and what rebuilds them) and its CPU time per stage to the dataset folder, then regenerates
the dataset's CARD.md. An object the dataset already holds is refused (batches must not recompute objects), and
nothing is written then. Exit status 2 on any such error, with one line naming the file or object.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("results", help="the run's results/ folder (results/lift and results/optimized, or results/model_batch; "
                        "results/objects, results/stability)")
    parser.add_argument("--dataset", required=True, help="the dataset folder (made if absent)")
    parser.add_argument("--logs", default=None, help="the run's snakemake benchmark files (default: RESULTS/../logs/benchmarks)")
    parser.add_argument("--kind", default=None, help="what made the grasps: optimization, model, loop_round_<r> (default: model for a "
                        "model-made batch, whose grasps keep their own source, else optimization)")


def run(args: argparse.Namespace) -> int:
    from datetime import datetime, timezone
    from pathlib import Path

    from dexlite_pipeline.dataset import BatchRecord, DatasetError, add_batch, code_version, dataset_summary, write_card
    from dexlite_pipeline.dataset.from_run import run_batch

    results = Path(args.results)
    batch = run_batch(results, args.logs)
    kind = args.kind or ("model" if batch.model_made else "optimization")
    if batch.model_made and kind != "model":
        raise DatasetError(f"{results / 'model_batch'}: a model-made batch is of kind model, not {kind}")
    if not batch.model_made and kind != "optimization":
        batch.grasps.arrays["source"][:] = kind

    def modified_utc(path: Path) -> str:
        return datetime.fromtimestamp(path.stat().st_mtime, timezone.utc).isoformat(timespec="seconds").replace("+00:00", "Z")

    # the code that made the grasps: the run folder's checkout when the run ran in one (a campaign batch runs in a
    # checkout of the batch's commit), else this package's
    run_checkout = results.resolve().parent
    made_by = code_version(run_checkout) if (run_checkout / "src" / "dexlite_pipeline").is_dir() else code_version()
    record = BatchRecord(kind=kind, code_version=made_by, config=batch.config, cpu_seconds=batch.cpu_seconds,
                         started_utc=modified_utc(results / "objects" / "catalog.parquet"),  # the first stage's output
                         finished_utc=max(modified_utc(p) for p in batch.shards), protocol=batch.protocol)
    batch_id = add_batch(args.dataset, batch.grasps, batch.objects, record)
    write_card(args.dataset, batch.protocol)
    summary = dataset_summary(args.dataset)
    held = int(batch.grasps.arrays["lift_success"].sum()) if len(batch.grasps) else 0
    print(f"batch {batch_id:04d}: {len(batch.objects)} objects, {len(batch.grasps)} lift-tested grasps, {held} held, "
          f"{sum(batch.cpu_seconds.values()):.0f} CPU-s -> {args.dataset} (now {summary.get('objects', '?')} objects)")
    for object_id, reason in batch.config.get("left_out_objects", {}).items():
        print(f"left out {object_id}: {reason}")
    return 0
