"""``dexlite report``: build ``results/eval/report.html`` from the evaluation outputs.

It takes the run's whole config (``--config-json``) and shows its key settings and the
whole of it in the page; of the ``evaluate`` section it reads ``report.steps.REPORT_KEYS``.
The run's ``seed`` seeds the random choice of pictured grasps; the page links the CSV
tables relative to where it is written.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", default="{}", help="the run's whole config as JSON (shown in the report)")
    parser.add_argument("--eval-dir", required=True, help="folder with metrics.csv, per_object.csv, convergence.csv, evaluation.json")
    parser.add_argument("--sim", action="append", default=[], help="simulated shard store(s) of the evaluation (for histograms and pictures)")
    parser.add_argument("--history", default=None, help="CVAE training history CSV (optional)")
    parser.add_argument("--objects", action="append", default=[], help="prepared objects dir (repeatable), for the pictures")
    parser.add_argument("--out", required=True, help="output HTML file")


def csv_links(eval_dir: Path, page_dir: Path) -> dict[str, str]:
    """The evaluation's CSV tables that exist, as links relative to the page's folder (the page opens from disk)."""
    import os

    from dexlite_pipeline.report.html import CSV_FILES

    return {name: Path(os.path.relpath(eval_dir / name, page_dir)).as_posix() for name in CSV_FILES if (eval_dir / name).is_file()}


def run(args: argparse.Namespace) -> int:
    import numpy as np
    import pandas as pd

    from dexlite_pipeline.config import parse_config_json
    from dexlite_pipeline.io.atomic import write_text_atomic
    from dexlite_pipeline.io.grasp_store import read_grasp_store
    from dexlite_pipeline.report.evaluation import concatenate_shards, evaluate_config_from
    from dexlite_pipeline.report.html import ReportInputs, build_report_html
    from dexlite_pipeline.report.steps import REPORT_KEYS

    config = parse_config_json(args.config_json)
    cfg = evaluate_config_from(config, REPORT_KEYS)
    eval_dir = Path(args.eval_dir)
    for name in ("metrics.csv", "per_object.csv", "convergence.csv"):
        if not (eval_dir / name).is_file():
            raise FileNotFoundError(f"{eval_dir / name}: evaluation output missing (run dexlite evaluate --step aggregate)")
    summary_path = eval_dir / "evaluation.json"
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else {}
    simulated = concatenate_shards([read_grasp_store(p) for p in args.sim])
    history = None
    if args.history and Path(args.history).is_file():
        history = pd.read_csv(args.history)
    budget_path = eval_dir / "budget.csv"
    budget = pd.read_csv(budget_path) if budget_path.is_file() and budget_path.stat().st_size else None
    inputs = ReportInputs(
        metrics=pd.read_csv(eval_dir / "metrics.csv"),
        per_object=pd.read_csv(eval_dir / "per_object.csv"),
        convergence=pd.read_csv(eval_dir / "convergence.csv"),
        history=history,
        simulated=simulated,
        lift_config=summary.get("lift_config") or {},
        objects_dirs=args.objects,
        rendered_per_method=cfg.rendered_per_method,
        config=config,
        csv_links=csv_links(eval_dir, Path(args.out).parent),
        seed=int(config.get("seed") or 0),
        budget=budget,
    )
    write_text_atomic(args.out, build_report_html(inputs))
    n_rendered = 0 if simulated is None else len(set(np.asarray(simulated.arrays.get("method", [])).tolist()))
    print(f"wrote {args.out} ({n_rendered} methods pictured)")
    return 0
