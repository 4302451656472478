"""The data loop's config type: section ``loop``.

A leaf of the config tree (``settings``): it imports no loop code, so a stage's code hash
(``codehash``) covers this shape without the rounds' computation (the other ``loop`` modules).
"""

from __future__ import annotations

from dataclasses import dataclass

from dexlite_pipeline.config import ConfigError
from dexlite_pipeline.model.config import ANCHOR_RULES


@dataclass(frozen=True)
class LoopConfig:
    """Config section ``loop``: how many rounds, and what one round samples and trains."""

    rounds: int = 0  # rounds after the first model (0 = no loop: the pipeline without it)
    grasps_per_object: int = 16  # grasps sampled per stable training object per round
    train_steps: int = 1000  # optimizer steps of each round's training, warm-started from the previous round's model
    six_directions: bool = True  # new grasps must also pass the six-direction test (off: the lift test alone)
    heldout_grasps_per_object: int = 8  # grasps per held-out object in each round's small held-out check (0 = none)
    # a round's training fine-tunes the previous model: train.learning_rate times this, constant, no warm-up, and the
    # energy terms at full weight from the first step (a fresh model's schedule would shake a trained one loose)
    fine_tune_learning_rate_factor: float = 0.1
    # associated points of a round's samples on the training objects (the sample section's rules): matched (where the
    # surface looks like that of the training grasp whose code was drawn; with match_candidates > 1 a debiased draw among
    # that many best matches) or debiased (Dex1B's 1/(count+1) over the whole cloud, whose samples rarely refine into
    # grasps that pass the energy thresholds with a model trained on a few grasps per object)
    anchor_rule: str = "matched"
    match_candidates: int = 1
    # annealed steps of a round's post-optimization (post_optimize's schedule otherwise; 0 = post_optimize.annealing.iterations):
    # what a round keeps must pass the energy thresholds, which short refinements of learned starts rarely reach
    post_iterations: int = 1000

    def __post_init__(self) -> None:
        for name in ("rounds", "grasps_per_object", "heldout_grasps_per_object", "post_iterations"):
            if getattr(self, name) < 0:
                raise ConfigError(f"loop.{name} must be >= 0, got {getattr(self, name)}")
        if self.train_steps < 1:
            raise ConfigError(f"loop.train_steps must be >= 1, got {self.train_steps}")
        if self.anchor_rule not in ANCHOR_RULES:
            raise ConfigError(f"loop.anchor_rule {self.anchor_rule!r} is not one of {', '.join(ANCHOR_RULES)}")
        if self.match_candidates < 1:
            raise ConfigError(f"loop.match_candidates must be >= 1, got {self.match_candidates}")
        if not 0 < self.fine_tune_learning_rate_factor <= 1:
            raise ConfigError(f"loop.fine_tune_learning_rate_factor must be in (0, 1], got {self.fine_tune_learning_rate_factor}")
