"""A round's sampling settings per part: the loop's own on the training objects, the evaluation's on the held-out ones."""

from __future__ import annotations

import dataclasses

from dexlite_pipeline.loop.config import LoopConfig
from dexlite_pipeline.loop.sample_round import LOOP_METHOD, round_sample_settings
from dexlite_pipeline.model.config import SampleConfig
from dexlite_pipeline.model.methods import SYNTHESIS


def test_the_training_part_samples_with_the_loops_anchor_rule_and_the_heldout_part_as_the_evaluation():
    sample = SampleConfig(anchor_rule="matched", match_candidates=1, neighbour_clouds=8)
    loop = LoopConfig(anchor_rule="debiased", match_candidates=16, grasps_per_object=12, heldout_grasps_per_object=3)
    train, count, label = round_sample_settings(sample, loop, "train")
    assert (train.anchor_rule, train.match_candidates, count, label) == ("debiased", 16, 12, LOOP_METHOD)
    assert dataclasses.replace(train, anchor_rule="matched", match_candidates=1) == sample  # nothing else changes
    heldout, count, label = round_sample_settings(sample, loop, "heldout")
    assert (heldout, count, label) == (sample, 3, SYNTHESIS)
