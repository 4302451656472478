"""A round's refinement (stage ``loop_post_optimize``): the ``post_optimize`` section the pipeline's
post-optimization runs on a round's samples."""

from __future__ import annotations

import dataclasses

from dexlite_pipeline.loop.config import LoopConfig
from dexlite_pipeline.loop.round_basics import TRAIN


def round_post_optimize_config(post_optimize, loop: LoopConfig, part: str):
    """The ``post_optimize`` section a round's refinement of part ``part`` runs: without the random-start baseline
    (the evaluation's), and on the training part for ``loop.post_iterations`` annealed steps when set (the same
    schedule's constants, run longer); the held-out check refines as the evaluation does, so it measures the same."""
    post_optimize = dataclasses.replace(post_optimize, random_baseline=False)
    if part == TRAIN and loop.post_iterations > 0:
        post_optimize = dataclasses.replace(post_optimize, annealing=dataclasses.replace(post_optimize.annealing, iterations=loop.post_iterations))
    return post_optimize
