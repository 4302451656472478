"""``dexlite report``: build the HTML report from the evaluation outputs.

It takes the run's whole config (``--config-json``) and shows its key settings and the
whole of it in the page; of the ``evaluate`` section it reads ``evaluation.step_keys.REPORT_KEYS``.
At the top: the report date, the code commit, the run's wall time (from ``--benchmarks``, the
jobs' benchmark files) and the machine (``report.run_facts``).
The run's ``seed`` seeds the random choice of pictured grasps; the page links the CSV
tables relative to where it is written (``report.inputs.load_report_inputs``).
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", default="{}", help="the run's whole config as JSON (shown in the report)")
    parser.add_argument("--metrics", required=True, help="metrics.csv of the evaluation")
    parser.add_argument("--per-object", required=True, help="per_object.csv of the evaluation")
    parser.add_argument("--convergence", required=True, help="convergence.csv of the evaluation")
    parser.add_argument("--budget", default=None, help="budget.csv of the evaluation (optional)")
    parser.add_argument("--record", default=None, help="evaluation.json of the evaluation (optional)")
    parser.add_argument("--sim", action="append", default=[], help="simulated shard store(s) of the evaluation (for histograms and pictures)")
    parser.add_argument("--history", default=None, help="CVAE training history CSV (optional)")
    parser.add_argument("--objects", action="append", default=[], help="prepared objects dir (repeatable), for the pictures")
    parser.add_argument("--learning-curve", default=None, help="the shipped model's learning curve (docs/learning_curve.csv; optional)")
    parser.add_argument("--loop", default=None, help="the data loop's table (results/loop.csv; optional): the \"Data loop\" section")
    parser.add_argument("--benchmarks", default=None, help="the run's job benchmark folder (logs/benchmarks; optional): the run's wall time")
    parser.add_argument("--out", required=True, help="output HTML file")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.config import parse_config_json
    from dexlite_pipeline.atomic import write_text_atomic
    from dexlite_pipeline.report.inputs import EvaluationFiles, load_report_inputs
    from dexlite_pipeline.report.page import build_report_html

    files = EvaluationFiles(args.metrics, args.per_object, args.convergence, args.budget, args.record)
    inputs = load_report_inputs(files, args.sim, args.history, args.objects, parse_config_json(args.config_json), args.out, args.learning_curve,
                                args.benchmarks, args.loop)
    write_text_atomic(args.out, build_report_html(inputs))
    print(f"wrote {args.out}")
    return 0
