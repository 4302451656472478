"""A lift ratio well above 1 is an object thrown by an unstable contact, not a held grasp."""

from __future__ import annotations

import numpy as np
from bar_grasps import grasp_set

from dexlite_pipeline.sim.config import LiftConfig
from dexlite_pipeline.sim.lift import launched, run_lift_tests
from dexlite_pipeline.sim.simulator import GraspSimulator


def test_the_bound_is_as_far_above_one_as_the_success_ratio_is_below():
    config = LiftConfig()  # success above 0.9: thrown above 1.1
    assert launched(1.02, config) == "" and launched(1.0999, config) == ""
    assert launched(1.11, config) == "simulation_unstable" and launched(18986.8, config) == "simulation_unstable"
    assert launched(1.11, LiftConfig(success_lift_ratio=0.7)) == ""  # 1.3 then
    assert launched(float("nan"), config) == ""


def test_a_thrown_object_fails_as_unstable_and_is_not_pushed(objects_dir, hooks, monkeypatch):
    """The simulator's own verdict for a ratio of 33 (what LEAP's stiff contacts gave) would be success; the test
    records it as simulation_unstable, keeps the ratio, and runs no six-direction pushes."""
    monkeypatch.setattr(GraspSimulator, "lift", lambda self, pose, quat, target: (33.65, ""))
    grasps = grasp_set([hooks["round_bar"]], ["round_bar"])
    result = run_lift_tests(grasps, [objects_dir], LiftConfig(six_directions=True), threads=1)
    assert result["failure_reason"].tolist() == ["simulation_unstable"] and not result["lift_success"][0]
    assert np.isclose(result["lift_ratio"][0], 33.65) and np.isnan(result["six_dir_translation_m"][0]).all()
