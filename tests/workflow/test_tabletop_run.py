"""Tabletop mode in the workflow: `scene.table` reruns exactly the stages that read it, and on a table no held
grasp of the run reaches below it."""

from __future__ import annotations


import pytest
from workflow_harness import downstream, planned_commands, planned_rules, run_snakemake, tiny_config, write_config

pytestmark = pytest.mark.slow

# The rules whose params carry section `scene` (docs/design.md, "Tabletop mode").
SCENE_RULES = {
    "optimize_grasps", "curate", "lift_validate", "train_cvae", "post_optimize", "evaluate_simulate", "report",
    "loop_sample", "loop_post_optimize", "loop_validate", "loop_train",  # the data loop's rounds, on each object's table
    "evaluator_examples", "sample_grasps",  # the generator samples in each object's table frame; the evaluator's examples are tested on the table
}  # fmt: skip
BEFORE_OPTIMIZATION = {"prepare_objects", "stability_filter", "import_dexgraspnet"}


def test_scene_section_reaches_exactly_its_rules(tmp_path):
    import json

    from workflow_harness import option_value

    (tmp_path / "meshes").mkdir()
    write_config(tmp_path / "run", tiny_config(tmp_path / "meshes"))
    commands = planned_commands(run_snakemake(tmp_path / "run", "--dry-run", "--printshellcmds", "--cores", "2", "all"))
    reading = {rule for rule, lines in commands.items() for line in lines if "--config-json" in line and "scene" in json.loads(option_value(line, "--config-json"))}
    assert reading == SCENE_RULES


def test_switching_the_table_off_reruns_its_stages_and_nothing_before_optimization(complete_run, scratch_copy):
    assert complete_run.config["scene"]["table"] is True  # the default
    config = {**complete_run.config, "scene": {"table": False}}
    write_config(scratch_copy, config)

    planned = planned_rules(scratch_copy)

    assert planned == downstream(complete_run.graph, SCENE_RULES & set(complete_run.graph))
    assert not planned & BEFORE_OPTIMIZATION
    assert {"optimize_grasps", "curate", "lift_validate", "train_cvae", "post_optimize", "evaluate"} <= planned


def test_on_a_table_no_held_grasp_of_the_run_reaches_below_it(complete_run):
    """Every lift-validated and every evaluated grasp that held: its hand wholly above its object's table."""
    import numpy as np

    from dexlite_pipeline.io.grasp_store import read_grasp_store
    from dexlite_pipeline.energy.table_clearance import grasp_table_depths
    from dexlite_pipeline.tabletop import TABLE_TOLERANCE_M, SupportPlanes

    results = complete_run.workdir / "results"
    planes = SupportPlanes.from_stability_table(results / "stability" / "stability.parquet")
    stores = sorted((results / "lift").glob("shard_*.zarr")) + sorted((results / "eval" / "sim").glob("shard_*.zarr"))
    held_total = 0
    for path in stores:
        grasps = read_grasp_store(path)
        held = grasps.select(np.asarray(grasps.arrays["lift_success"], bool))
        held_total += len(held)
        depth = grasp_table_depths(held, planes)
        assert np.isfinite(depth).all() and (depth <= TABLE_TOLERANCE_M).all(), (path, depth.max() if len(depth) else None)
        if "hand_in_table" in set(grasps.arrays["failure_reason"].tolist()):
            rejected = grasps.select(grasps.arrays["failure_reason"] == "hand_in_table")
            assert (grasp_table_depths(rejected, planes) > TABLE_TOLERANCE_M).all()
    assert held_total > 0, "the tiny run held no grasp: the check above saw nothing"
