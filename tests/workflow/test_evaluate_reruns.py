"""An `evaluate` setting reruns only the evaluation steps that read it (evaluation.step_keys), after a complete run.

evaluate_simulate (the MuJoCo shards) tracks what chooses and measures the grasps; the
aggregate step (rule `evaluate`) what metrics.csv holds; the report the whole config. With the learned evaluator on,
sample_grasps reads the cap too (it keeps as many ranked rows per object as the evaluation simulates), so the cap
reruns the sampling and what follows it.
"""

from __future__ import annotations

import copy
import shutil

import pytest
from workflow_harness import downstream, planned_rules, write_config

pytestmark = pytest.mark.slow

EVALUATION_STEPS = {"evaluate_simulate", "evaluate", "report"}
CHANGES = [
    ("rendered_per_method", {"report"}),
    ("entropy_bins", {"evaluate", "report"}),
    ("pca_components", {"evaluate", "report"}),
    ("grasps_per_object", None),  # the sampling and what follows it (below)
]


def _changed(value):
    return [*value, max(value) + 1] if isinstance(value, list) else value + 1


@pytest.mark.parametrize(("key", "steps"), CHANGES, ids=[key for key, _ in CHANGES])
def test_evaluate_setting_reruns_only_the_steps_that_read_it(complete_run, tmp_path, key, steps):
    workdir = tmp_path / "run"
    shutil.copytree(complete_run.workdir, workdir, symlinks=True)
    config = copy.deepcopy(complete_run.config)
    config["evaluate"][key] = _changed(config["evaluate"][key])
    write_config(workdir, config)

    if steps is None:
        assert complete_run.config["evaluator"]["enabled"]
        steps = downstream(complete_run.graph, {"sample_grasps"}) | EVALUATION_STEPS
    assert planned_rules(workdir) == steps, f"evaluate.{key}"
