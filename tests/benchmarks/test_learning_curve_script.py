"""benchmarks/experiments/learning_curve.py: point folders, their config overlay, the table and the break-even arithmetic."""

import json
import math
from pathlib import Path

import pandas as pd
import pytest
import torch

RATES = ("lift_success_rate", "lift_success_ci95_low", "lift_success_ci95_high", "six_dir_success_rate", "six_dir_success_ci95_low", "six_dir_success_ci95_high")


@pytest.fixture(scope="module")
def curve(benchmark_script):
    return benchmark_script("learning_curve")


def test_point_folders_and_overlays_name_their_budget(curve):
    run = Path("/runs/large")
    assert curve.point_dir(run, 40, 1) == run / "curve" / "n40_seed1"
    assert curve.point_dir(run, 0, 0, 16000) == run / "curve" / "nall_seed0_steps16000"
    assert curve.point_overlay(40, 1)["train"] == {"seed": 1, "max_training_objects": 40}  # a training seed: the run's data and samples stay
    assert curve.point_overlay(0, 0, 16000)["train"] == {"seed": 0, "max_training_objects": 0, "max_steps": 16000}
    assert "seed" not in curve.point_overlay(40, 1)
    assert curve.point_dir(run, 0, 0, 0, 4) == run / "curve" / "nall_g4_seed0"
    assert curve.point_overlay(0, 2, 0, 4)["train"] == {"seed": 2, "max_training_objects": 0, "max_grasps_per_object": 4}
    assert curve.point_dir(run, 0, 1, 0, 0, 6) == run / "curve" / "nall_f6_seed1"
    assert curve.point_overlay(0, 1, 0, 0, 6)["train"] == {"seed": 1, "max_training_objects": 0, "max_training_families": 6}


def test_break_even_solves_equal_cost_per_successful_grasp(curve):
    # CVAE: 100 CPU-s of training, then 0.2 s per grasp at 40%; random: 0.1 s per grasp at 10% (1 s per success)
    n = curve.break_even_grasps(100.0, 0.4, 0.2, 0.1, 0.1)
    assert math.isclose(n, 500.0)
    assert math.isclose((100.0 + n * 0.2) / (n * 0.4), 0.1 / 0.1)
    assert curve.break_even_grasps(100.0, 0.1, 0.2, 0.4, 0.1) == math.inf  # never cheaper


def _metrics(folder: Path, rates: dict) -> None:
    rows = [{"method": m, "split": "heldout", "n_grasps": 768, **{c: r for c in RATES}, "seconds_per_grasp": 0.2 if m != "optimization" else 1.0}
            for m, r in rates.items()]  # fmt: skip
    (folder / "results" / "eval").mkdir(parents=True)
    pd.DataFrame(rows).to_csv(folder / "results" / "eval" / "metrics.csv", index=False)
    (folder / "results" / "model").mkdir(parents=True)
    torch.save({"train_object_ids": ["a", "b"], "train_grasps": 6, "steps": 16000 if "steps" in folder.name else 8000},
               folder / "results" / "model" / "cvae.pt")  # fmt: skip
    (folder / "logs" / "benchmarks").mkdir(parents=True)
    (folder / "logs" / "benchmarks" / "train_cvae.tsv").write_text("s\tcpu_time\n12.0\t100.0\n")


def test_table_holds_every_point_its_steps_and_the_run_baselines(curve, tmp_path):
    _metrics(tmp_path, {"cvae_raw": 0.1, "cvae_post": 0.4, "random_post": 0.1, "optimization": 0.6})
    for name in ("n10_seed0", "nall_seed0_steps16000"):
        point = tmp_path / "curve" / name
        _metrics(point, {"cvae_raw": 0.05, "cvae_post": 0.3})
        (point / "curve.yaml").write_text(json.dumps({"seed": 0}))
    table = curve.curve_table(tmp_path)
    assert sorted(set(table.point)) == ["all", "n10_seed0", "nall_seed0_steps16000", "optimization from scratch", "random init + post"]
    steps = table.set_index(["point", "method"]).training_steps
    assert steps["nall_seed0_steps16000", "cvae_post"] == 16000 and steps["all", "cvae_post"] == 8000
    assert pd.isna(steps["random init + post", "random_post"])
    run_post = table[(table.point == "all") & (table.method == "cvae_post")].iloc[0]
    # random starts: 0.2 s per grasp at 10% = 2 s per success; CVAE: (100 + 0.2 N) / 0.4 N = 2  ->  N = 100 / 0.6
    assert math.isclose(run_post.break_even_grasps_vs_random_post, 100.0 / 0.6)
