"""Config key ``hand`` in the workflow (dry runs): an unknown hand stops it while parsing, in one line naming the key;
with another hand than the Shadow Hand the data and model stages take it (optimize_grasps, curate, lift_validate,
train_cvae, sample_grasps, post_optimize, the learned evaluator's stages and evaluate are given it, prepare_objects and
stability_filter are not) and the default target, which needs the report, refuses at once."""

from __future__ import annotations

import json
import subprocess

from workflow_harness import option_value, planned_commands, snakemake_command, snakemake_env, tiny_config, write_config


def _dry_run(tmp_path, hand: str, *targets: str, dexgraspnet: bool = False) -> subprocess.CompletedProcess:
    config = {**tiny_config(tmp_path / "meshes"), "hand": hand}
    if not dexgraspnet:
        config["dexgraspnet"] = {**config["dexgraspnet"], "root": ""}
    write_config(tmp_path / "run", config)
    command = snakemake_command(tmp_path / "run", "--dry-run", "--printshellcmds", "--cores", "1", *targets)
    return subprocess.run(command, env=snakemake_env(), capture_output=True, text=True, timeout=300)


def test_an_unknown_hand_stops_the_workflow_in_one_line(tmp_path):
    done = _dry_run(tmp_path, "alegro")
    output = done.stdout + done.stderr
    assert done.returncode != 0 and "hand: alegro: not a hand name and no such file" in output and "Job stats" not in output


def test_another_hand_reaches_the_data_stages_and_the_default_target_refuses(tmp_path):
    done = _dry_run(tmp_path, "allegro")
    output = done.stdout + done.stderr
    assert done.returncode != 0 and "hand: allegro: the data loop, the report and the dataset stages know the Shadow Hand only" in output and "Job stats" not in output

    done = _dry_run(tmp_path, "allegro", "results/lift/shard_000.zarr", dexgraspnet=True)
    output = done.stdout + done.stderr
    assert done.returncode != 0 and "hand: allegro: dexgraspnet.root holds the Shadow Hand's grasps" in output

    done = _dry_run(tmp_path, "allegro", "results/lift/shard_000.zarr")
    output = done.stdout + done.stderr
    assert done.returncode == 0, output[-3000:]
    commands = planned_commands(output)
    assert set(commands) == {"prepare_objects", "stability_filter", "optimize_grasps", "curate", "lift_validate"}
    for rule, told in (("prepare_objects", False), ("stability_filter", False), ("optimize_grasps", True), ("curate", True),
                       ("lift_validate", True)):
        given = json.loads(option_value(commands[rule][0], "--config-json"))
        assert given.get("hand") == ("allegro" if told else None), rule


def test_another_hand_reaches_the_model_stages_and_the_evaluation(tmp_path):
    """Training, the learned evaluator's stages, sampling, post-optimization and the evaluation are given the hand; the
    Shadow Hand's runs are given no ``hand`` (their params, and so their outputs, unchanged)."""
    for hand in ("allegro", "shadow"):
        done = _dry_run(tmp_path / hand, hand, "results/eval/metrics.csv")
        output = done.stdout + done.stderr
        assert done.returncode == 0, output[-3000:]
        commands = planned_commands(output)
        rules = ("train_cvae", "evaluator_examples", "train_evaluator", "sample_grasps", "post_optimize", "evaluate_simulate", "evaluate")
        assert set(rules) <= set(commands)
        for rule in rules:
            given = json.loads(option_value(commands[rule][0], "--config-json"))
            assert given.get("hand") == ("allegro" if hand == "allegro" else None), (hand, rule)
