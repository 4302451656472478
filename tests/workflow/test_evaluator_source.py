"""Config key ``evaluator.source`` in the workflow (dry runs): ``shipped`` or a file ranks the held-out syntheses with
that evaluator and plans no examples and no evaluator training; a missing file stops the workflow in one line."""

from __future__ import annotations

import subprocess

import torch

from workflow_harness import checkout, option_value, planned_commands, snakemake_command, snakemake_env, tiny_config, write_config

from dexlite_pipeline.model.shipped import PACKAGE_DATA, shipped_evaluator_path


def _dry_run(tmp_path, source: str) -> subprocess.CompletedProcess:
    config = tiny_config(tmp_path / "meshes", evaluator={"enabled": True, "source": source})
    write_config(tmp_path / "run", config)
    command = snakemake_command(tmp_path / "run", "--dry-run", "--forceall", "--printshellcmds", "--cores", "1", "all")
    return subprocess.run(command, env=snakemake_env(), capture_output=True, text=True, timeout=300)


def _ranking_evaluators(output: str) -> set[str]:
    return {option_value(line, "--evaluator") for line in planned_commands(output)["sample_grasps"]}


def test_the_trained_evaluator_ranks_by_default(tmp_path):
    done = _dry_run(tmp_path, "train")
    output = done.stdout + done.stderr
    assert done.returncode == 0, output[-3000:]
    assert {"evaluator_examples", "train_evaluator"} <= set(planned_commands(output))
    assert _ranking_evaluators(output) == {"results/evaluator/evaluator.pt"}


def test_the_shipped_evaluator_ranks_without_examples_or_training(tmp_path):
    done = _dry_run(tmp_path, "shipped")
    output = done.stdout + done.stderr
    assert done.returncode == 0, output[-3000:]
    planned = set(planned_commands(output))
    assert "sample_grasps" in planned and not planned & {"evaluator_examples", "train_evaluator"}
    # the package's evaluator of the frozen checkout the workflow runs on
    packaged = shipped_evaluator_path("shadow").relative_to(PACKAGE_DATA.parents[1])
    assert _ranking_evaluators(output) == {str(checkout() / "src" / packaged)}


def test_an_evaluator_file_ranks_and_a_missing_one_stops_the_workflow(tmp_path):
    given = tmp_path / "run" / "mine.pt"
    given.parent.mkdir(parents=True)
    torch.save({"format": "placeholder"}, given)  # the plan only needs the file to exist; loading it is sample_grasps' job
    done = _dry_run(tmp_path, "mine.pt")
    output = done.stdout + done.stderr
    assert done.returncode == 0, output[-3000:]
    assert _ranking_evaluators(output) == {"mine.pt"}

    done = _dry_run(tmp_path, "elsewhere/evaluator.pt")
    output = done.stdout + done.stderr
    assert done.returncode != 0 and "evaluator.source: elsewhere/evaluator.pt: no such evaluator file" in output
    assert "Job stats" not in output
