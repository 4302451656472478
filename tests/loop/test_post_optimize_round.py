"""A round's refinement settings per part: longer on the training part, the evaluation's on the held-out check."""

from __future__ import annotations

import dataclasses

from dexlite_pipeline.loop.config import LoopConfig
from dexlite_pipeline.loop.post_optimize_round import round_post_optimize_config
from dexlite_pipeline.optim.config import PostOptimizeConfig


def test_a_rounds_training_part_refines_for_loop_post_iterations_and_the_heldout_check_as_the_evaluation():
    post = PostOptimizeConfig(random_baseline=True)
    longer = round_post_optimize_config(post, LoopConfig(post_iterations=600), "train")
    assert longer.annealing.iterations == 600 and not longer.random_baseline
    assert dataclasses.replace(longer.annealing, iterations=post.annealing.iterations) == post.annealing  # the same schedule, longer
    assert round_post_optimize_config(post, LoopConfig(post_iterations=600), "heldout").annealing == post.annealing
    assert round_post_optimize_config(post, LoopConfig(post_iterations=0), "train").annealing == post.annealing
