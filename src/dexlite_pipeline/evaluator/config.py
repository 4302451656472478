"""The learned evaluator's config type: section ``evaluator``.

A leaf of the config tree (``settings``): it imports no evaluator code, so a stage's code hash
(``codehash``) covers this shape without the network or the simulation.
"""

from __future__ import annotations

from dataclasses import dataclass

from dexlite_pipeline.config import ConfigError, setting


@dataclass(frozen=True)
class EvaluatorSection:
    """Config section ``evaluator``: whether the pipeline trains a grasp evaluator and ranks the model's samples by it."""

    enabled: bool = setting(
        True, "train a grasp evaluator on the run's simulated grasps (training objects only) and add the evaluation rows "
        "cvae_ranked / cvae_ranked_post: the model draws pool_factor x more pure syntheses per held-out object and keeps the "
        "best-scored distinct ones (default run, seeds 0-2: 1.7-2.3x the held grasps per simulated attempt of unranked "
        "samples, docs/results.md); false drops those rows")
    source: str = setting(
        "train", "the evaluator that ranks (with enabled): train (one trained by the run on its own model's examples and "
        "training grasps), shipped (the one shipped with the run's hand: no examples, no evaluator training; how a new "
        "model is measured ranked as the shipped model is) or the path of an evaluator.pt of the same hand")
    examples_per_object: int = setting(
        48, "on-generator examples: the trained model's pure syntheses per stable training object, post-optimized and "
        "simulated (every one, held or not) as the evaluation does; ~0.1 CPU s each (default run: 40-62 CPU s per shard)", minimum=0)
    pool_factor: int = setting(
        32, "candidates the model draws per grasp the evaluator keeps: dexlite grasp keeps the best-scored distinct --n of "
        "pool_factor x --n samples per object (diversity's rule, topped up with the next best when fewer are distinct); "
        "the ranked rows keep as many as the evaluation simulates per object (evaluate.grasps_per_object) of pool_factor "
        "times as many; model batches and the data loop rank the same way", minimum=1)
    epochs: int = setting(40, "passes over the training examples", minimum=1)
    hand_points_per_shape: int = setting(6, "hand surface points per collision shape the network reads (6 -> 114 points)", minimum=1)
    rotation_augmentation: bool = setting(
        True, "turn each training cloud, its grasps and their tables about the object's z axis (up on the table) by a random "
        "angle every step: it scores grasps on new objects as they stand, at any heading (the model's samples are turned "
        "back from the matched heading, sample.yaw_candidates)")
    validation_fraction: float = setting(
        0.2, "share of the training OBJECTS whose grasps only validate (the epoch with the lowest validation loss is kept)",
        minimum=0, exclusive_maximum=1)

    def __post_init__(self) -> None:
        if not str(self.source).strip():
            raise ConfigError("evaluator.source is empty: give train, shipped or the path of an evaluator.pt")
        if self.examples_per_object < 0:
            raise ConfigError(f"evaluator.examples_per_object must be >= 0, got {self.examples_per_object}")
        for name in ("pool_factor", "epochs", "hand_points_per_shape"):
            if getattr(self, name) < 1:
                raise ConfigError(f"evaluator.{name} must be >= 1, got {getattr(self, name)}")
        if not 0 <= self.validation_fraction < 1:
            raise ConfigError(f"evaluator.validation_fraction must be in [0, 1), got {self.validation_fraction}")
