"""A code edit plans exactly the stages that run the edited code, and what consumes their outputs.

Each test edits a copy of the package and computes the plan of ``snakemake -n`` on a finished
run without needing one: the rules whose ``code`` param changes (each rule's
``code_hash(...)`` call in workflow/rules, hashed by ``codehash.code_hash`` over the copy, as
the workflow hashes the package it finds first on PYTHONPATH), and every rule downstream of
them in the rule graph (``snakemake --rulegraph`` of the real Snakefile). That is the plan
``snakemake -n`` makes on a finished run where only the package changed: its params trigger
reruns a job whose recorded params differ from the current ones; the ``cfg`` params are JSON of
the config, which did not change; the ``code`` trigger covers the rule's own shell/run text in
the .smk files, which did not change either; and a planned job's outputs are newer than what
consumes them, so Snakemake plans every consumer, transitively. The slow test at the end checks
the same edits with a real ``snakemake -n`` on the finished tiny run (``complete_run``).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import pytest
from workflow_harness import checkout, downstream, planned_rules, rule_code_modules, rule_graph, tiny_config, write_config, write_tiny_meshes

from dexlite_pipeline.codehash import code_hash

UPSTREAM_OF_LIFT = frozenset({"prepare_objects", "stability_filter", "optimize_grasps", "import_dexgraspnet", "curate", "curate_summary"})


@dataclass(frozen=True)
class CodeEdit:
    module_file: str  # path under src/dexlite_pipeline/
    changed: frozenset[str]  # rules whose code hash the edit changes: exactly those that run the code
    first_planned: frozenset[str]  # the plan is these and everything downstream of them
    not_planned: frozenset[str]  # stages the edit cannot affect


# The data loop's stages (loop.smk): each imports the loop module of its own step (loop.sample_round, loop.merge, ...)
# and the few the steps share, so an edit changes the hash of the loop stages that run the edited code only.
LOOP_STAGES = frozenset({
    "loop_initial_set", "loop_sample", "loop_post_optimize", "loop_validate", "loop_merge", "loop_train", "loop_summary", "loop_table",
})  # fmt: skip
READS_FINAL_MODEL = frozenset({"sample_grasps", "post_optimize", "evaluate_simulate", "evaluate"})

EDITS = {
    # the network: training and sampling run it (the evaluator's examples and its PointNet too), and the loop's steps that train,
    # sample or load a model (round 0's set,
    # whose stage imports the training's shard reader; the summary reads a round model's checkpoint); the plan is
    # training onwards and the loop's round 0 set
    "network": CodeEdit(
        "model/network.py", frozenset({"train_cvae", "sample_grasps", "loop_initial_set", "loop_sample", "loop_train", "loop_summary",
                                       "evaluator_examples", "train_evaluator"}),
        frozenset({"train_cvae", "loop_initial_set"}), UPSTREAM_OF_LIFT | {"lift_validate"},
    ),
    # the lift test: lift validation and the evaluation's simulation (and the report, which reads the evaluation's
    # protocol) run it, and of the loop only its validation; nothing before lift validation reruns
    "lift test": CodeEdit(
        "sim/lift.py", frozenset({"lift_validate", "evaluate_simulate", "evaluate", "report", "loop_validate", "evaluator_examples"}),
        frozenset({"lift_validate"}),
        UPSTREAM_OF_LIFT,
    ),
    # the optimizer: optimization from scratch and post-optimization (the loop's too) run it; preparation and stability do not
    "optimizer": CodeEdit(
        "optim/annealing.py", frozenset({"optimize_grasps", "post_optimize", "loop_post_optimize", "evaluator_examples"}),
        frozenset({"optimize_grasps", "post_optimize", "loop_post_optimize"}), frozenset({"prepare_objects", "stability_filter", "import_dexgraspnet"}),
    ),
    # the loop table: only its own stage runs it; the plan is that stage and the report that shows the table
    "loop table": CodeEdit(
        "loop/table.py", frozenset({"loop_table"}), frozenset({"loop_table"}),
        UPSTREAM_OF_LIFT | {"lift_validate", "train_cvae"} | (LOOP_STAGES - {"loop_table"}) | READS_FINAL_MODEL,
    ),
}


def one_grasp_dataset(folder: Path) -> Path:
    """A grasp dataset of one tested grasp (so that a dataset.root config has the dataset_grasps rule)."""
    import numpy as np
    import pandas as pd

    from dexlite_pipeline.dataset import BatchRecord, add_batch
    from dexlite_pipeline.dataset.layout import REQUIRED_ARRAYS
    from dexlite_pipeline.io.grasp_store import GraspSet

    arrays = {name: np.full((1, *spec.trailing_shape), np.nan, np.float32) for name, spec in REQUIRED_ARRAYS.items() if spec.kind == "float32"}
    arrays.update(object_id=np.array(["user-box"], dtype=object), scale=np.full(1, 0.1, np.float32), lift_success=np.ones(1, bool),
                  six_dir_success=np.ones(1, bool), failure_reason=np.array([""], dtype=object), source=np.array(["optimization"], dtype=object))
    arrays["hand_pose"] = np.zeros((1, 28), np.float32)
    record = BatchRecord(kind="optimization", code_version="0" * 40, config={}, cpu_seconds={}, started_utc="2026-01-01T00:00:00Z",
                         finished_utc="2026-01-01T00:00:01Z", protocol="test", machine="test")
    add_batch(folder, GraspSet(arrays, {}), pd.DataFrame({"object_id": ["user-box"], "source": ["user"], "split": ["train"]}), record)
    return folder


@pytest.fixture(scope="module")
def graph(tmp_path_factory) -> dict[str, set[str]]:
    """The rule graph of the tiny config with a DexGraspNet import configured (every rule in it)."""
    scratch = tmp_path_factory.mktemp("code_reruns")
    download = scratch / "dexgraspnet"
    (download / "dataset").mkdir(parents=True)
    config = tiny_config(write_tiny_meshes(scratch / "meshes"), dexgraspnet={"root": str(download), "heldout_object_codes": []},
                         dataset={"root": str(one_grasp_dataset(scratch / "dataset"))})
    write_config(scratch / "run", config)
    return rule_graph(scratch / "run")


def rule_hashes(package: Path) -> dict[str, str]:
    """Rule -> its ``code`` param computed over the package at ``package``."""
    return {rule: code_hash(*modules, root=package) for rule, modules in rule_code_modules().items()}


def planned(graph: dict[str, set[str]], before: dict[str, str], after: dict[str, str]) -> tuple[set[str], set[str]]:
    """(rules whose code param changed, the plan: those and every rule downstream of them)."""
    changed = {rule for rule in graph if before.get(rule) != after.get(rule)}
    return changed, downstream(graph, changed)


@pytest.mark.parametrize("name", list(EDITS))
def test_code_edit_plans_the_stages_that_run_it_and_downstream_only(graph, tmp_path, name):
    edit = EDITS[name]
    package = tmp_path / "dexlite_pipeline"
    shutil.copytree(checkout() / "src" / "dexlite_pipeline", package, ignore=shutil.ignore_patterns("__pycache__"))
    # every rule of the graph passes a code hash; the only hashed rule outside `all` is the model-made batch's (its own target)
    assert set(rule_code_modules()) - (set(graph) - {"all"}) == {"model_batch"}, "a hashed rule outside the graph"
    assert set(graph) - {"all"} <= set(rule_code_modules()), "every rule of the graph passes a code hash"
    before = rule_hashes(package)
    edited = package / edit.module_file
    original = edited.read_text()

    edited.write_text(original + "\nCODE_CHANGE_PROBE = 1\n")
    changed, plan = planned(graph, before, rule_hashes(package))

    assert changed == edit.changed
    assert plan == downstream(graph, set(edit.first_planned))
    assert not plan & edit.not_planned, sorted(plan & edit.not_planned)

    edited.write_text(original)  # the edit undone: nothing is planned
    assert planned(graph, before, rule_hashes(package)) == (set(), set())


@pytest.mark.slow
@pytest.mark.parametrize("name", list(EDITS))
def test_snakemake_plans_the_same_on_a_finished_run(complete_run, tmp_path, name):
    """The real ``snakemake -n`` on the finished tiny run, with the edited copy first on PYTHONPATH."""
    edit = EDITS[name]
    source = tmp_path / "src"
    shutil.copytree(checkout() / "src" / "dexlite_pipeline", source / "dexlite_pipeline", ignore=shutil.ignore_patterns("__pycache__"))
    edited = source / "dexlite_pipeline" / edit.module_file
    original = edited.read_text()

    edited.write_text(original + "\nCODE_CHANGE_PROBE = 1\n")
    plan = planned_rules(complete_run.workdir, env={"PYTHONPATH": str(source)})

    assert plan == downstream(complete_run.graph, set(edit.first_planned))
    assert not plan & edit.not_planned, sorted(plan & edit.not_planned)

    edited.write_text(original)
    assert planned_rules(complete_run.workdir, env={"PYTHONPATH": str(source)}) == set()
