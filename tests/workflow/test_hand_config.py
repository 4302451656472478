"""Config key ``hand`` in the workflow (dry runs): an unknown hand stops it while parsing, in one line naming the key;
with another hand than the Shadow Hand the data and model stages take it (optimize_grasps, curate, lift_validate,
train_cvae, sample_grasps, post_optimize, the learned evaluator's stages, evaluate, the data loop, the report,
dataset_grasps and model_batch are given it, prepare_objects and stability_filter are not), the default target included."""

from __future__ import annotations

import json
import subprocess

from workflow_harness import option_value, planned_commands, snakemake_command, snakemake_env, tiny_config, write_config


def _dry_run(tmp_path, hand: str, *targets: str, dexgraspnet: bool = False, **sections) -> subprocess.CompletedProcess:
    config = {**tiny_config(tmp_path / "meshes"), "hand": hand, **sections}
    if not dexgraspnet:
        config["dexgraspnet"] = {**config["dexgraspnet"], "root": ""}
    write_config(tmp_path / "run", config)
    command = snakemake_command(tmp_path / "run", "--dry-run", "--printshellcmds", "--cores", "1", *targets)
    return subprocess.run(command, env=snakemake_env(), capture_output=True, text=True, timeout=300)


def test_an_unknown_hand_stops_the_workflow_in_one_line(tmp_path):
    done = _dry_run(tmp_path, "alegro")
    output = done.stdout + done.stderr
    assert done.returncode != 0 and "hand: alegro: not a hand name and no such file" in output and "Job stats" not in output


def test_another_hand_reaches_every_stage_of_the_default_target(tmp_path):
    """The default target with a data loop round: every rule but prepare_objects and stability_filter is given the hand."""
    config = {**tiny_config(tmp_path / "meshes"), "hand": "allegro"}
    config["dexgraspnet"] = {**config["dexgraspnet"], "root": ""}
    config["loop"] = {**config.get("loop", {}), "rounds": 1}
    write_config(tmp_path / "run", config)
    done = subprocess.run(snakemake_command(tmp_path / "run", "--dry-run", "--printshellcmds", "--cores", "1"), env=snakemake_env(),
                          capture_output=True, text=True, timeout=300)
    output = done.stdout + done.stderr
    assert done.returncode == 0, output[-3000:]
    commands = planned_commands(output)
    assert {"loop_sample", "loop_post_optimize", "loop_validate", "loop_merge", "loop_train", "loop_summary", "report"} <= set(commands)
    for rule, lines in commands.items():
        if "--config-json" in lines[0] and rule not in ("prepare_objects", "stability_filter"):
            assert json.loads(option_value(lines[0], "--config-json")).get("hand") == "allegro", rule


def test_another_hand_reaches_the_data_stages(tmp_path):

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


def test_another_hand_reaches_the_model_made_batch(tmp_path):
    """model_batch_all (a dataset batch made by the model) gives model_batch the hand; the Shadow Hand's, none. The
    shipped model it takes by default is the hand's: without one the workflow stops while parsing, naming the key."""
    from dexlite_pipeline.model.shipped import SHIPPED_MODEL_PATH, shipped_model_path

    if shipped_model_path("leap") is None:
        done = _dry_run(tmp_path / "leap", "leap", "model_batch_all")
        output = done.stdout + done.stderr
        assert done.returncode != 0 and "model_batch.model: 'shipped': no shipped model at " in output
        assert "(not shipped for hand leap, or the package was installed without its data)" in output
    for hand in ("allegro", "shadow"):
        # a file for the hand (the dry run reads only its name): the hand's shipped model, else any file
        model = "shipped" if shipped_model_path(hand) else str(SHIPPED_MODEL_PATH)
        done = _dry_run(tmp_path / hand, hand, "model_batch_all", model_batch={"model": model, "evaluator": "none"})
        output = done.stdout + done.stderr
        assert done.returncode == 0, output[-3000:]
        commands = planned_commands(output)
        assert "model_batch" in commands
        for line in commands["model_batch"]:
            assert json.loads(option_value(line, "--config-json")).get("hand") == ("allegro" if hand == "allegro" else None), hand
