"""``dexlite evaluate``: simulate every method's grasps on the evaluated objects and tabulate the metrics.

Two steps, so that the heavy simulation is sharded like the other grasp-heavy stages
(``evaluation.shards``):

- ``--step simulate --shard K``: the K-th shard of every method's grasp stores, chosen,
  simulated and measured, to ``--out``;
- ``--step aggregate``: all simulated shards plus the post-optimization traces to
  ``--metrics``, ``--per-object``, ``--convergence``, ``--budget`` and ``--record``.

Each step reads only its keys of the ``evaluate`` section (``evaluation.step_keys``), the keys
its rule tracks, so a report-only setting does not rerun the simulation.
"""

from __future__ import annotations

import argparse

from dexlite_pipeline.evaluation.step_keys import SOURCE_OPTIONS

AGGREGATE_OUTPUTS = ("metrics", "per-object", "convergence", "budget", "record")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--step", choices=("simulate", "aggregate"), required=True)
    parser.add_argument("--config-json", default="{}", help="config sections (seed, device, shards, hand, evaluate, lift, energy, scene) as JSON")
    parser.add_argument("--objects", action="append", default=[], help="prepared objects dir (repeatable); their catalogs give the splits")
    for key, option in SOURCE_OPTIONS.items():
        parser.add_argument(f"--{option}", dest=key, action="append", default=[], help=f"{key} grasp store(s) (repeatable)")
    parser.add_argument("--shard", type=int, default=None, help="simulate: shard index (selects the DexGraspNet objects of this shard)")
    parser.add_argument("--stability", help="simulate: stability table with the objects' resting poses (tables in tabletop mode; "
                        "reachability on the table in both modes)")
    parser.add_argument("--sim", action="append", default=[], help="aggregate: simulated shard store(s)")
    parser.add_argument("--out", help="simulate: output grasp store")
    for name in AGGREGATE_OUTPUTS:
        kind = "JSON record of the evaluation" if name == "record" else f"{name} table (.csv)"
        parser.add_argument(f"--{name}", help=f"aggregate: output {kind}")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.config import parse_config_json
    from dexlite_pipeline.evaluation.shards import aggregate_evaluation, simulate_shard, write_evaluation
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.settings import build_config

    config = parse_config_json(args.config_json)
    tree = build_config(config)
    if args.step == "simulate":
        if not args.out or args.shard is None:
            raise ValueError("evaluate --step simulate needs --out and --shard")
        result, attrs = simulate_shard(
            {key: getattr(args, key) for key in SOURCE_OPTIONS}, args.objects, args.shard, config, energy=tree.energy, scene=tree.scene,
            seed=tree.seed, shards=tree.shards, device=tree.device, threads=args.threads or 1, stability_path=args.stability, hand=tree.hand,
        )
        write_grasp_store(args.out, result, attrs)
        print(f"evaluate shard {args.shard}: simulated {len(result)} grasps -> {args.out}")
        return 0
    outputs = [getattr(args, name.replace("-", "_")) for name in AGGREGATE_OUTPUTS]
    if not args.sim or not all(outputs):
        raise ValueError("evaluate --step aggregate needs --sim and " + ", ".join(f"--{n}" for n in AGGREGATE_OUTPUTS))
    tables = aggregate_evaluation(args.sim, args.post, args.random_post, args.objects, config, diversity=tree.diversity, seed=tree.seed,
                                  hand=tree.hand)
    write_evaluation(tables, *outputs)
    columns = ["method", "split", "n_grasps", "n_invalid", "lift_success_rate", "six_dir_success_rate", "distinct_held_per_object_mean",
               "surface_coverage_mean", "energy_threshold_pass_rate", "filtered_lift_success_rate", "cpu_seconds_per_distinct_held_grasp"]  # fmt: skip
    print(tables.metrics[[c for c in columns if c in tables.metrics.columns]].to_string(index=False))
    return 0
