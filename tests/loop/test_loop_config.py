"""Config section loop refuses values no round can run with."""

from __future__ import annotations

import pytest

from dexlite_pipeline.config import ConfigError
from dexlite_pipeline.loop.config import LoopConfig


@pytest.mark.parametrize(
    "bad", [{"rounds": -1}, {"train_steps": 0}, {"grasps_per_object": -2}, {"anchor_rule": "nearest"}, {"match_candidates": 0}, {"post_iterations": -1}]
)
def test_loop_config_refuses_bad_values(bad):
    with pytest.raises(ConfigError):
        LoopConfig(**bad)


@pytest.mark.parametrize("factor", [0.0, -0.1, 1.5])
def test_a_fine_tune_factor_outside_0_1_is_refused(factor):
    with pytest.raises(ConfigError, match="fine_tune_learning_rate_factor"):
        LoopConfig(fine_tune_learning_rate_factor=factor)
