"""The data loop's config type: section ``loop``.

A leaf of the config tree (``settings``): it imports no loop code, so a stage's code hash
(``codehash``) covers this shape without the rounds' computation (the other ``loop`` modules).
"""

from __future__ import annotations

from dataclasses import dataclass

from dexlite_pipeline.config import ConfigError, rule_keys, setting
from dexlite_pipeline.model.config import ANCHOR_RULES


@dataclass(frozen=True)
class LoopConfig:
    """Config section ``loop``: how many rounds, and what one round samples and trains."""

    # rules: the loop rules that pass the key to their stage (LOOP_RULE_SECTIONS); none tracks rounds, whose number adds
    # or drops rounds' jobs instead
    rounds: int = setting(
        0, "rounds after the first model (0 = no loop: the pipeline's outputs exactly as without it); the evaluation's cvae_* "
        "rows use the last round's model. Off by default: whether two rounds raise held-out success is measured on one seed "
        "only (docs/results.md; large profile: 4)", minimum=0)
    grasps_per_object: int = setting(
        16, "grasps sampled per stable training object per round (loop.anchor_rule), those without any grasp yet included; a "
        "round costs about 0.8 CPU s per sampled grasp", minimum=0, rules=("loop_sample",))
    train_steps: int = setting(
        1000, "optimizer steps of each round's training, warm-started from the previous round's model (the first model's "
        "train.max_steps: 8000 from scratch)", minimum=1, rules=("loop_train",))
    six_directions: bool = setting(
        True, "a new grasp must also pass the six-direction test (DexGraspBench), not only the lift test", rules=("loop_validate",))
    heldout_grasps_per_object: int = setting(
        8, "each round's model is also checked on the held-out objects (sample, post-optimize, lift test) with this many grasps "
        "per object: the held-out curve over rounds (0 = none)", minimum=0, rules=("loop_sample",))
    fine_tune_learning_rate_factor: float = setting(
        0.1, "a round fine-tunes the last model at train.learning_rate x this, constant, with no learning-rate or energy "
        "warm-up: the energy terms at full weight from the first step (a fresh model's schedule would shake the trained one "
        "loose)", exclusive_minimum=0, maximum=1, rules=("loop_train",))
    anchor_rule: str = setting(
        "matched", "associated points of a round's samples: matched (where the surface looks like that of the drawn code's "
        "training grasp) or debiased (Dex1B: weight 1/(count+1) over the whole cloud, whose samples rarely refine into grasps "
        "that pass the energy thresholds with a model trained on a few grasps per object); matched keeps 2.5-5x more new "
        "grasps per round (docs/results.md, benchmarks/experiments/loop_round_yield.py)", enum=ANCHOR_RULES, rules=("loop_sample",))
    rank_candidates: bool = setting(
        False, "draw evaluator.pool_factor x grasps_per_object candidates per training object and keep the grasps_per_object "
        "best-scored distinct ones by the learned evaluator (needs evaluator.enabled)", rules=("loop_sample",))
    match_candidates: int = setting(
        1, "matched: a debiased draw among this many best-matching points (1 = the best match)", minimum=1, rules=("loop_sample",))
    post_iterations: int = setting(
        1000, "annealed steps of a round's post-optimization of its samples (0 = post_optimize.annealing.iterations): what a "
        "round keeps must pass the energy thresholds, which short refinements of learned starts rarely reach; 1000 steps "
        "keep ~3x more than 200 at equal CPU per grasp kept", minimum=0, rules=("loop_post_optimize",))

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


# The config each loop rule passes its stage (workflow/rules/loop.smk; benchmarks/experiments/loop_round_yield.py runs the
# stages alike): these sections and dotted keys, then the keys of section loop whose ``setting(rules=...)`` names the rule.
LOOP_RULE_SECTIONS = {
    "loop_sample": ("seed", "device", "shards", "sample", "scene"),
    "loop_post_optimize": ("seed", "device", "post_optimize", "scene", "energy.self_penetration_margin_m"),
    "loop_validate": ("device", "curate.thresholds", "energy.weights", "lift", "scene"),
    "loop_merge": ("diversity",),
    "loop_train": ("seed", "device", "train", "scene", "energy.self_penetration_margin_m"),
    "loop_summary": ("diversity",),
}


def loop_rule_sections(rule: str) -> tuple[str, ...]:
    """The sections and dotted keys loop rule ``rule`` passes its stage (``stage_params``)."""
    return (*LOOP_RULE_SECTIONS[rule], *(f"loop.{key}" for key in rule_keys(LoopConfig, rule)))
