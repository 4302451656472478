"""How early an optimization from scratch is known to miss the energy thresholds.

    python benchmarks/experiments/early_stop_signal.py RUN/results [--shard 0 --shards 4] [--out OUT.csv]

Optimizes one shard of a run's stable objects with the package's default config, keeps every grasp's energy terms every ``trace_every`` iterations, and asks for each checkpoint
iteration and each rule "stop a grasp whose kept state at the checkpoint has E_fc > a and E_dis > b" (a, b from
a grid): what share of the grasp-iterations after the checkpoint it saves and what share of the grasps that
finally pass the energy thresholds it would have stopped. Prints the table; ``--out`` writes it as CSV.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def traced_shard(results: Path, shard: int, shards: int, seed: int):
    """(grasps, term traces (name -> (T, B)), trace iterations) of one shard optimized with the default config."""
    import dexlite_pipeline.optim.from_scratch as from_scratch
    from dexlite_pipeline.optim.from_scratch_shard import optimize_shard
    from dexlite_pipeline.settings import build_config

    config = build_config({"optimize_grasps": {"stop_hopeless": {"iterations": [], "max_e_fc": [], "max_e_dis_m": []}}})  # every grasp to the end
    captured = []
    original = from_scratch.optimize

    def capturing(*args, **kwargs):
        result = original(*args, **kwargs)
        captured.append(result)
        return result

    from_scratch.optimize = capturing
    try:
        grasps, _ = optimize_shard([str(results / "objects")], str(results / "stability" / "stability.parquet"), shard, shards=shards,
                                   optimize_grasps=config.optimize_grasps, energy=config.energy, scene=config.scene, seed=seed, device="cpu")
    finally:
        from_scratch.optimize = original
    traces = {name: np.concatenate([r.term_traces[name].numpy() for r in captured], axis=1) for name in captured[0].term_traces}
    return grasps, traces, captured[0].trace_iterations.numpy(), config.optimize_grasps.annealing.iterations


def rule_table(passes: np.ndarray, traces: dict, iterations: np.ndarray, total_iterations: int) -> list[dict]:
    rows = []
    for checkpoint in (200, 400, 600, 800, 1000, 1200):
        row_index = int(np.searchsorted(iterations, checkpoint))
        e_fc, e_dis = traces["E_fc"][row_index], traces["E_dis"][row_index]
        for max_fc in (0.5, 0.8, 1.0, 1.5, 2.0, np.inf):
            for max_dis in (0.01, 0.02, 0.03, 0.05, np.inf):
                if np.isinf(max_fc) and np.isinf(max_dis):
                    continue
                stop = (e_fc > max_fc) | (e_dis > max_dis)
                saved = stop.mean() * (total_iterations - checkpoint) / total_iterations
                rows.append({"checkpoint": checkpoint, "max_e_fc": max_fc, "max_e_dis_m": max_dis, "stopped": float(stop.mean()),
                             "iterations_saved": float(saved), "passing_lost": float((stop & passes).sum() / max(passes.sum(), 1))})
    return rows


def configured_rule(passes: np.ndarray, traces: dict, iterations: np.ndarray, total_iterations: int) -> dict:
    """The default config's checkpoints applied in turn: share of grasps stopped, of iterations saved, of passing grasps lost."""
    from dexlite_pipeline.settings import build_config

    stop = build_config({}).optimize_grasps.stop_hopeless
    walking, saved = np.ones(len(passes), bool), 0.0
    for checkpoint, max_fc, max_dis in zip(stop.iterations, stop.max_e_fc, stop.max_e_dis_m):
        row_index = int(np.searchsorted(iterations, checkpoint))
        stopping = walking & ((traces["E_fc"][row_index] > max_fc) | (traces["E_dis"][row_index] > max_dis))
        saved += stopping.sum() * (total_iterations - checkpoint)
        walking &= ~stopping
    return {"checkpoints": list(stop.iterations), "stopped": float((~walking).mean()), "iterations_saved": saved / (len(passes) * total_iterations),
            "passing_lost": float((~walking & passes).sum() / max(passes.sum(), 1))}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path)
    parser.add_argument("--shard", type=int, default=0)
    parser.add_argument("--shards", type=int, default=4)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--traces", type=Path, default=None, help="an earlier --out's .npz: tabulate it instead of optimizing again")
    args = parser.parse_args(argv)
    import pandas as pd

    if args.traces:
        saved = np.load(args.traces)
        passes, iterations = saved["passes"], saved["iterations"]
        traces = {k.removeprefix("trace_"): saved[k] for k in saved.files if k.startswith("trace_")}
        total_iterations = int(iterations[-1])
    else:
        grasps, traces, iterations, total_iterations = traced_shard(args.results, args.shard, args.shards, args.seed)
        passes = np.asarray(grasps.arrays["passes_energy_thresholds"], bool)
    print(f"{len(passes)} grasps, {passes.sum()} pass the energy thresholds ({passes.mean():.1%})")
    table = pd.DataFrame(rule_table(passes, traces, iterations, total_iterations))
    print("the default stop_hopeless:", configured_rule(passes, traces, iterations, total_iterations))
    best = table[table["passing_lost"] <= 0.03].sort_values("iterations_saved", ascending=False)
    print(best.head(25).to_string(index=False))
    if args.out:
        table.to_csv(args.out, index=False)
        np.savez_compressed(args.out.with_suffix(".npz"), passes=passes, iterations=iterations, **{f"trace_{k}": v for k, v in traces.items()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
