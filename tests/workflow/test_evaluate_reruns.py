"""An `evaluate` setting reruns only the evaluation steps that read it (evaluation.step_keys), after a complete run.

evaluate_simulate (the MuJoCo shards) tracks what chooses and measures the grasps; the
aggregate step (rule `evaluate`) what metrics.csv holds; the report the whole config.
"""

from __future__ import annotations

import copy
import shutil

import pytest
from workflow_harness import planned_rules, write_config

pytestmark = pytest.mark.slow

EVALUATION_STEPS = {"evaluate_simulate", "evaluate", "report"}
CHANGES = [
    ("rendered_per_method", {"report"}),
    ("entropy_bins", {"evaluate", "report"}),
    ("pca_components", {"evaluate", "report"}),
    ("grasps_per_object", EVALUATION_STEPS),
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

    assert planned_rules(workdir) == steps, f"evaluate.{key}"
