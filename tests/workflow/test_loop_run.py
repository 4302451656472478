"""The data loop in the tiny run (two rounds): its outputs, their counts, and what changing loop.rounds reruns."""

from __future__ import annotations

import copy
import json
import shlex

import numpy as np
import pandas as pd
import pytest
import torch
from workflow_harness import job_blocks, option_value, planned_commands, run_snakemake, tiny_config, wildcard, write_config

from dexlite_pipeline.config import merge_config
from dexlite_pipeline.evaluation.diversity import distinct_grasp_labels
from dexlite_pipeline.io.grasp_store import read_grasp_store
from dexlite_pipeline.loop.merge import grasp_groups
from dexlite_pipeline.loop.round_basics import DROP_REASONS

pytestmark = pytest.mark.slow

LOOP_RULES = {"loop_sample", "loop_post_optimize", "loop_validate", "loop_merge", "loop_train", "loop_summary"}
# the evaluator learns from the final model's samples (evaluator_examples, train_evaluator), and ranks them
READS_FINAL_MODEL = {"evaluator_examples", "train_evaluator", "sample_grasps", "post_optimize", "evaluate_simulate", "evaluate", "report"}


def _distinct(grasps) -> int:
    labels = distinct_grasp_labels(grasps.hand_pose, grasp_groups(grasps))
    return int(labels.max() + 1) if len(labels) else 0


def _validated(folder, part="train"):
    """The round's validated candidates of ``part``, all shards in order (shards without objects hold no rows)."""
    stores = [read_grasp_store(path) for path in sorted((folder / part).glob("validated_*.zarr"))]
    return [store for store in stores if len(store)]


def test_the_tiny_loop_keeps_new_distinct_grasps_that_passed_every_check(complete_run):
    results = complete_run.workdir / "results"
    config = complete_run.config
    assert config["loop"]["rounds"] == 2
    limits = {"filter_E_fc": config["curate"]["thresholds"]["max_e_fc"], "filter_E_dis": config["curate"]["thresholds"]["max_e_dis_m"],
              "E_pen": config["curate"]["thresholds"]["max_e_pen_m"]}  # fmt: skip
    table = pd.read_csv(results / "loop.csv")
    assert table["round"].tolist() == [0, 1, 2]
    previous = read_grasp_store(results / "round_0" / "grasps.zarr")
    for round_number in (1, 2):
        folder = results / f"round_{round_number}"
        row = table.set_index("round").loc[round_number]
        # every candidate is kept or dropped for one reason, and the counts add up
        candidates = _validated(folder)
        reasons = np.concatenate([np.asarray(v.arrays["drop_reason"]).astype(str) for v in candidates])
        assert set(reasons) <= {"", *DROP_REASONS} and len(reasons) == row["sampled"] > 0
        assert row["sampled"] == row["kept"] + sum(row[r] for r in DROP_REASONS)
        assert row["kept"] + row["duplicate"] == (reasons == "").sum()
        for store in candidates:  # a candidate that reached the merge passed the filter, the lift and six-direction tests
            passed = np.asarray(store.arrays["drop_reason"]).astype(str) == ""
            for name, limit in limits.items():
                assert (np.asarray(store.arrays[name])[passed] < limit).all()
            assert store.arrays["lift_success"][passed].all() and store.arrays["six_dir_success"][passed].all()
        # the set is the previous one plus the kept grasps, each a new distinct grasp taken from those that passed
        grasps = read_grasp_store(folder / "grasps.zarr")
        assert len(grasps) == len(previous) + row["kept"]
        np.testing.assert_array_equal(grasps.hand_pose[: len(previous)], previous.hand_pose)
        assert (grasps.arrays["round"][len(previous):] == round_number).all()
        passed_poses = np.concatenate([v.hand_pose[np.asarray(v.arrays["drop_reason"]).astype(str) == ""] for v in candidates])
        for new_pose in grasps.hand_pose[len(previous):]:
            assert (np.abs(passed_poses - new_pose).max(axis=1) == 0).any()
        assert _distinct(grasps) == _distinct(previous) + row["kept"]
        summary = pd.read_csv(folder / "summary.csv")
        assert summary["grasps"].sum() == len(grasps) and summary["kept"].sum() == row["kept"]
        checkpoint = torch.load(folder / "model" / "cvae.pt", weights_only=True)
        started_from = "results/model/cvae.pt" if round_number == 1 else f"results/round_{round_number - 1}/model/cvae.pt"
        assert checkpoint["initial_model"] == started_from and checkpoint["steps"] == config["loop"]["train_steps"]
        previous = grasps
    assert table.loc[1:, "kept"].sum() > 0  # the merge is exercised by real grasps, not only by the unit tests
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


def _forced_plan(workdir, config) -> dict[str, list[str]]:
    write_config(workdir, config)
    return planned_commands(run_snakemake(workdir, "--dry-run", "--forceall", "--printshellcmds", "--cores", "2", "all"))


def _config_json(command: str) -> str:
    return option_value(command, "--config-json")


def test_no_rounds_plan_the_workflow_without_the_loop(tmp_path):
    """loop.rounds 0: no loop job, and every other job's command (so its params) is the one it has with rounds, less what
    the rounds change by design: the model the evaluation samples from (the last round's) and the report's loop table."""
    (tmp_path / "meshes").mkdir()
    config = tiny_config(tmp_path / "meshes")
    rounds = _forced_plan(tmp_path / "rounds", config)
    assert all("--model results/round_2/model/cvae.pt" in c for c in rounds["sample_grasps"])
    no_rounds = _forced_plan(tmp_path / "zero", merge_config(config, {"loop": {"rounds": 0}}))
    assert not {rule for rule in no_rounds if rule.startswith("loop_")}
    assert set(no_rounds) == {rule for rule in rounds if not rule.startswith("loop_")}
    for rule, commands in no_rounds.items():
        expected = [c.replace("results/round_2/model/cvae.pt", "results/model/cvae.pt") for c in rounds[rule]]
        if rule == "report":
            (with_loop,) = expected
            shown = json.loads(_config_json(with_loop))
            assert shown["loop"] == config["loop"] and json.loads(_config_json(commands[0])) == {k: v for k, v in shown.items() if k != "loop"}
            with_loop = with_loop.replace(shlex.quote(_config_json(with_loop)), shlex.quote(_config_json(commands[0])))
            expected = [with_loop.replace("--loop results/loop.csv ", "")]
        assert sorted(commands) == sorted(expected), rule
