"""The data loop in the tiny run (two rounds): its outputs, their counts, and what changing loop.rounds reruns."""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd
import pytest
import torch
from workflow_harness import job_blocks, planned_commands, run_snakemake, tiny_config, wildcard, write_config

from dexlite_pipeline.evaluation.diversity import distinct_grasp_labels
from dexlite_pipeline.io.grasp_store import read_grasp_store
from dexlite_pipeline.loop.rounds import DROP_REASONS, grasp_groups

pytestmark = pytest.mark.slow

LOOP_RULES = {"loop_sample", "loop_post_optimize", "loop_validate", "loop_merge", "loop_train", "loop_summary"}
READS_FINAL_MODEL = {"sample_grasps", "post_optimize", "evaluate_simulate", "evaluate", "report"}


def _distinct(grasps) -> int:
    labels = distinct_grasp_labels(grasps.hand_pose, grasp_groups(grasps))
    return int(labels.max() + 1) if len(labels) else 0


def test_the_tiny_loop_grows_its_set_by_distinct_grasps_only(complete_run):
    results = complete_run.workdir / "results"
    assert complete_run.config["loop"]["rounds"] == 2
    table = pd.read_csv(results / "loop.csv")
    assert table["round"].tolist() == [0, 1, 2]
    previous = read_grasp_store(results / "round_0" / "grasps.zarr")
    for round_number in (1, 2):
        folder = results / f"round_{round_number}"
        grasps = read_grasp_store(folder / "grasps.zarr")
        row = table.set_index("round").loc[round_number]
        assert row["sampled"] == row["kept"] + sum(row[r] for r in DROP_REASONS) > 0
        # the set is the previous one plus the kept grasps, each a new distinct grasp
        assert len(grasps) == len(previous) + row["kept"]
        np.testing.assert_array_equal(grasps.hand_pose[: len(previous)], previous.hand_pose)
        assert (grasps.arrays["round"][len(previous):] == round_number).all()
        assert _distinct(grasps) == _distinct(previous) + row["kept"]
        summary = pd.read_csv(folder / "summary.csv")
        assert summary["grasps"].sum() == len(grasps) and summary["kept"].sum() == row["kept"]
        checkpoint = torch.load(folder / "model" / "cvae.pt", weights_only=True)
        started_from = "results/model/cvae.pt" if round_number == 1 else f"results/round_{round_number - 1}/model/cvae.pt"
        assert checkpoint["initial_model"] == started_from and checkpoint["steps"] == complete_run.config["loop"]["train_steps"]
        previous = grasps
    assert (table["heldout_attempts"] > 0).all() and (table.loc[1:, "cpu_seconds"] > 0).all()
    assert "<h2>Data loop</h2>" in (results / "eval" / "report.html").read_text()


def _planned(workdir, config):
    write_config(workdir, config)
    return job_blocks(run_snakemake(workdir, "--dry-run", "--cores", "2", "all"))


def test_more_rounds_plan_only_the_new_round_and_what_reads_the_final_model(complete_run, scratch_copy):
    config = copy.deepcopy(complete_run.config)
    config["loop"]["rounds"] = 3
    jobs = _planned(scratch_copy, config)
    rules = {job["rule"] for job in jobs} - {"all"}
    assert rules == LOOP_RULES | {"loop_table"} | READS_FINAL_MODEL
    assert {wildcard(job, "round") for job in jobs if job["rule"] in LOOP_RULES} == {"3"}


def test_fewer_rounds_rerun_only_what_reads_the_final_model(complete_run, scratch_copy):
    config = copy.deepcopy(complete_run.config)
    config["loop"]["rounds"] = 1
    rules = {job["rule"] for job in _planned(scratch_copy, config)} - {"all"}
    assert rules == READS_FINAL_MODEL | {"loop_table"}


def test_the_evaluation_samples_from_the_last_rounds_model(tmp_path):
    (tmp_path / "meshes").mkdir()
    write_config(tmp_path / "run", tiny_config(tmp_path / "meshes"))
    commands = planned_commands(run_snakemake(tmp_path / "run", "--dry-run", "--forceall", "--printshellcmds", "--cores", "2", "all"))
    assert all("--model results/round_2/model/cvae.pt" in c for c in commands["sample_grasps"])


def _forced_plan(workdir, config) -> dict[str, list[str]]:
    write_config(workdir, config)
    return planned_commands(run_snakemake(workdir, "--dry-run", "--forceall", "--printshellcmds", "--cores", "2", "all"))


def test_no_rounds_plan_the_workflow_without_the_loop(tmp_path):
    """loop.rounds 0 plans the same jobs with the same commands (so the same params) as a config without the section."""
    (tmp_path / "meshes").mkdir()
    config = tiny_config(tmp_path / "meshes", loop={"rounds": 0})
    without = {k: v for k, v in copy.deepcopy(config).items() if k != "loop"}
    no_rounds = _forced_plan(tmp_path / "zero", config)
    assert not {rule for rule in no_rounds if rule.startswith("loop_")}
    assert no_rounds == _forced_plan(tmp_path / "without", without)
    assert all("--model results/model/cvae.pt" in c for c in no_rounds["sample_grasps"])
    assert all('"loop"' not in c for c in no_rounds["report"])
