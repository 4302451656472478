"""The learning curve: how held-out success grows with the number of training families, objects and grasps per object.

Takes a large run whose data stages are done (``results/lift`` complete; see
``config/profiles/large.yaml``) and, for each object count and training seed, trains a model on
a seeded subset of that many of the run's training objects (``train.max_training_objects``;
subsets of one seed are nested), optionally with at most ``--grasps-per-object`` grasps of each
(``train.max_grasps_per_object``, nested too) or only the objects of ``--families`` of their families
(``train.max_training_families``: a household family, procedural, other; nested too), and evaluates it on the run's held-out objects — the benchmark
split — with the run's own rules and budget: ``sample.synthesis_grasps_per_object`` syntheses per
object, ``evaluate.grasps_per_object`` of them simulated, ``post_optimize.annealing.iterations``
post-optimization steps. Every point is a directory ``<run>/curve/n<count>[_f<families>][_g<grasps>]_seed<seed>/`` holding
hard links of the run's data stages (``results/objects``, ``stability``, ``optimized``, ``curate``,
``lift``) in which Snakemake runs the workflow from ``train_cvae`` on (``--rerun-triggers mtime``:
the linked outputs are kept as they are). The run's own model is the curve's "all objects" point.
Random init + post-optimization and optimization from scratch (``optimization``) do not depend on the
model: they are read from the run. For CVAE + post-optimization each point also gets the number of
generated grasps after which it, training CPU time included, costs fewer CPU-seconds per
lift-successful grasp than each of them (``break_even_grasps``; inf: never).

    python benchmarks/experiments/learning_curve.py --run RUN --counts 10 40 160 --seeds 0      # train and evaluate the points
    python benchmarks/experiments/learning_curve.py --run RUN --counts 0 --grasps-per-object 4 12  # all objects, fewer grasps each
    python benchmarks/experiments/learning_curve.py --run RUN --counts 0 --families 4 12  # the objects of fewer families
    python benchmarks/experiments/learning_curve.py --run RUN --tabulate --out docs/learning_curve  # table and plot only

``--out`` gets ``<out>.csv`` (one row per point and method) and ``<out>.png``; the Markdown table
is printed. Each point's Snakemake log is ``<point>/curve.log``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

from dexlite_pipeline.report.learning_curve import BASELINES, CURVE_METHODS, curve_markdown, save_curve_figure

DATA_STAGES = ("objects", "stability", "optimized", "curate", "lift", "dataset")  # "dataset": a run trained from the grasp dataset
RATE_COLUMNS = (
    "lift_success_rate", "lift_success_ci95_low", "lift_success_ci95_high",
    "six_dir_success_rate", "six_dir_success_ci95_low", "six_dir_success_ci95_high",
)  # fmt: skip


def point_dir(run: Path, count: int, seed: int, max_steps: int = 0, grasps_per_object: int = 0, families: int = 0) -> Path:
    """``<run>/curve/n<count>[_f<families>][_g<grasps_per_object>]_seed<seed>[_steps<max_steps>]``; count 0 is every
    training object (``nall``), families 0 every family, grasps_per_object 0 every grasp of each."""
    grasps = f"_g{grasps_per_object}" if grasps_per_object else ""
    family = f"_f{families}" if families else ""
    return run / "curve" / (f"n{count or 'all'}{family}{grasps}_seed{seed}" + (f"_steps{max_steps}" if max_steps else ""))


def link_data_stages(run: Path, point: Path) -> None:
    """Hard links of the run's data-stage outputs in ``point/results`` (timestamps kept, so they count as done)."""
    for stage in DATA_STAGES:
        source, target = run / "results" / stage, point / "results" / stage
        if source.exists() and not target.exists():
            target.parent.mkdir(parents=True, exist_ok=True)
            subprocess.run(["cp", "-al", str(source), str(target)], check=True)


def point_overlay(count: int, seed: int, max_steps: int = 0, grasps_per_object: int = 0, families: int = 0) -> dict:
    """Config on top of the run's: the subsets (families, objects, grasps per object), the training seed (``train.seed``: the run's
    data and sampling seeds stay), the step budget when given, held-out CVAE rows only (no learned evaluator: the curve
    measures the generator)."""
    return {
        "train": {"seed": seed, "max_training_objects": count, **({"max_grasps_per_object": grasps_per_object} if grasps_per_object else {}),
                  **({"max_training_families": families} if families else {}),
                  **({"max_steps": max_steps} if max_steps else {})},
        "sample": {"ladder": False, "expansion_grasps_per_object": 0, "shipped_model": ""},
        "post_optimize": {"random_baseline": False},
        "evaluate": {"methods": list(CURVE_METHODS)},
        "evaluator": {"enabled": False},
    }


def run_point(
    run: Path, configfiles: list[str], count: int, seed: int, cores: int, dry_run: bool = False, max_steps: int = 0, grasps_per_object: int = 0,
    families: int = 0,
) -> None:
    """Train and evaluate one point with the run's workflow (its Snakefile and package source)."""
    point = point_dir(run, count, seed, max_steps, grasps_per_object, families)
    point.mkdir(parents=True, exist_ok=True)
    link_data_stages(run, point)
    overlay = point / "curve.yaml"
    overlay.write_text(json.dumps(point_overlay(count, seed, max_steps, grasps_per_object, families), indent=1))  # JSON is YAML
    command = [
        "snakemake", "--snakefile", str(run / "Snakefile"), "--directory", str(point), "--cores", str(cores),
        "--configfile", *[str(run / c) for c in configfiles], str(overlay),
        "--rerun-triggers", "mtime", *(["--dry-run"] if dry_run else []), "--", "results/eval/metrics.csv",
    ]  # fmt: skip
    started = time.perf_counter()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(run / "src"), os.environ.get("PYTHONPATH")]))}  # the run's own code
    with open(point / "curve.log", "w") as log:
        subprocess.run(command, check=True, stdout=log, stderr=subprocess.STDOUT, env=env)
    print(f"{point.name}: done in {time.perf_counter() - started:.0f} s", flush=True)


def _training_cpu_seconds(folder: Path) -> float:
    """CPU seconds of the point's train_cvae job (Snakemake's benchmark file), NaN if absent."""
    path = folder / "logs" / "benchmarks" / "train_cvae.tsv"
    return float(pd.read_csv(path, sep="\t")["cpu_time"].iloc[0]) if path.exists() else float("nan")


def _model_facts(folder: Path) -> dict:
    import torch

    checkpoint = torch.load(folder / "results" / "model" / "cvae.pt", map_location="cpu", weights_only=True)
    return {"training_objects": len(checkpoint.get("train_object_ids") or []), "training_grasps": int(checkpoint.get("train_grasps", 0)),
            "training_steps": int(checkpoint.get("steps") or 0)}


def curve_table(run: Path) -> pd.DataFrame:
    """One row per (point, method): the points under ``run/curve`` and the run itself (all objects), then the
    run's model-free baselines (``BASELINES``); CVAE + post-optimization rows get their break-even grasp counts."""
    folders = sorted((run / "curve").glob("n*_seed*")) if (run / "curve").exists() else []
    rows = []
    for folder, is_run in [(run, True), *[(f, False) for f in folders]]:
        metrics_path = folder / "results" / "eval" / "metrics.csv"
        if not metrics_path.exists():
            print(f"{folder}: no metrics.csv yet, skipped", file=sys.stderr)
            continue
        metrics = pd.read_csv(metrics_path)
        overlay = {} if is_run else json.loads((folder / "curve.yaml").read_text())
        seed = _point_seed(overlay) if not is_run else _run_seed(run)
        facts = {"point": "all" if is_run else folder.name, "seed": seed, **_model_facts(folder),
                 "grasps_per_object_cap": int(overlay.get("train", {}).get("max_grasps_per_object", 0)),
                 "families_cap": int(overlay.get("train", {}).get("max_training_families", 0)),
                 "training_cpu_s": _training_cpu_seconds(folder)}
        for method in CURVE_METHODS:
            row = metrics[(metrics.method == method) & (metrics.split == "heldout")]
            if len(row):
                rows.append({**facts, "method": method, "n_grasps": int(row.n_grasps.iloc[0]),
                             **{c: float(row[c].iloc[0]) for c in RATE_COLUMNS}, "seconds_per_grasp": float(row.seconds_per_grasp.iloc[0])})
    table = pd.DataFrame(rows)
    run_metrics_path = run / "results" / "eval" / "metrics.csv"
    run_metrics = pd.read_csv(run_metrics_path) if run_metrics_path.exists() else pd.DataFrame(columns=["method", "split"])
    for method, (label, _) in BASELINES.items():
        baseline = run_metrics[(run_metrics.method == method) & (run_metrics.split == "heldout")]
        if len(baseline):
            extra = {"point": label, "seed": _run_seed(run), "training_objects": 0, "training_grasps": 0, "training_cpu_s": 0.0,
                     "method": method, "n_grasps": int(baseline.n_grasps.iloc[0]), **{c: float(baseline[c].iloc[0]) for c in RATE_COLUMNS},
                     "seconds_per_grasp": float(baseline.seconds_per_grasp.iloc[0])}  # fmt: skip
            table = pd.concat([table, pd.DataFrame([extra])], ignore_index=True)
    if "training_steps" in table:
        table["training_steps"] = table["training_steps"].astype("Int64")  # baselines have none
    for method in BASELINES:
        reference = table[table.method == method]
        column = f"break_even_grasps_vs_{method}"
        table[column] = float("nan")
        if len(reference):
            rate, seconds = float(reference.lift_success_rate.iloc[0]), float(reference.seconds_per_grasp.iloc[0])
            post = table.method == "cvae_post"
            table.loc[post, column] = [
                break_even_grasps(r.training_cpu_s, r.lift_success_rate, r.seconds_per_grasp, rate, seconds) for r in table[post].itertuples()
            ]
    return table


def _point_seed(overlay: dict) -> int:
    """A point's training seed: ``train.seed`` of its overlay (points made before it existed: the run seed they set)."""
    return int(overlay["train"]["seed"]) if "seed" in overlay.get("train", {}) else int(overlay["seed"])


def _run_seed(run: Path) -> int:
    record = run / "results" / "eval" / "evaluation.json"
    return int(json.loads(record.read_text()).get("config", {}).get("seed", 0)) if record.exists() else 0


def break_even_grasps(training_cpu_s: float, cvae_rate: float, cvae_s: float, random_rate: float, random_s: float) -> float:
    """Grasps generated after which CVAE + post-optimization, training included, costs fewer CPU-seconds per
    lift-successful grasp than random init + post-optimization (inf when it never does).

    Per successful grasp: CVAE (T + N·c)/(N·p), random r/q; solving (T + N·c)/(N·p) = r/q gives N = T / (p·r/q - c).
    """
    margin = cvae_rate * random_s / random_rate - cvae_s if random_rate > 0 else float("inf")
    return training_cpu_s / margin if margin > 0 else float("inf")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", required=True, type=Path, help="directory of a large run (a checkout with results/)")
    parser.add_argument("--configfile", nargs="+", default=["config.yaml", "config/profiles/large.yaml"], help="the run's config files, relative to --run")
    parser.add_argument("--counts", nargs="*", type=int, default=[10, 40, 160], help="training-object counts (0: all of them)")
    parser.add_argument("--grasps-per-object", nargs="*", type=int, default=[0], help="caps on training grasps per object (0: all)")
    parser.add_argument("--families", nargs="*", type=int, default=[0], help="training-family counts (0: every family)")
    parser.add_argument("--max-steps", type=int, default=0, help="training step budget of these points (0: the run's train.max_steps)")
    parser.add_argument("--seeds", nargs="*", type=int, default=[0], help="training seeds")
    parser.add_argument("--cores", type=int, default=2)
    parser.add_argument("--tabulate", action="store_true", help="only tabulate the points already run")
    parser.add_argument("--dry-run", action="store_true", help="plan every point's jobs (Snakemake --dry-run, in each point's curve.log) and stop")
    parser.add_argument("--out", type=Path, default=Path("docs/learning_curve"), help="output prefix: <out>.csv and <out>.png")
    args = parser.parse_args(argv)
    run = args.run.resolve()
    if not args.tabulate:
        if not (run / "results" / "lift").exists():
            parser.error(f"{run}/results/lift: missing; run the large profile's data stages first")
        for seed in args.seeds:
            for count in args.counts:
                for grasps in args.grasps_per_object:
                    for families in args.families:
                        run_point(run, args.configfile, count, seed, args.cores, args.dry_run, args.max_steps, grasps, families)
        if args.dry_run:
            return 0
    table = curve_table(run)
    if table.empty:
        print(f"{run}: no evaluated points", file=sys.stderr)
        return 1
    args.out.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.out.with_suffix(".csv"), index=False)
    save_curve_figure(table, args.out.with_suffix(".png"))
    print(curve_markdown(table))
    for row in table[table.method == "cvae_post"].itertuples():
        print(f"{row.point}: CVAE + post-optimization, training included, costs fewer CPU-seconds per lift-successful grasp than "
              + "; ".join(f"{m} after {getattr(row, f'break_even_grasps_vs_{m}'):.0f} grasps" for m in BASELINES))
    return 0


if __name__ == "__main__":
    sys.exit(main())
