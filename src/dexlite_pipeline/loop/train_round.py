"""A round's training (stage ``loop_train``): the ``train`` section that fine-tunes the previous round's model."""

from __future__ import annotations

import dataclasses

from dexlite_pipeline.loop.config import LoopConfig


def round_training_config(train, loop: LoopConfig):
    """The ``train`` section for one round's training: ``loop.train_steps`` steps fine-tuning the previous round's
    model at ``train.learning_rate * loop.fine_tune_learning_rate_factor``, constant, with no learning-rate warm-up
    and the energy terms at full weight from the first step (the model is trained already)."""
    return dataclasses.replace(
        train, max_steps=loop.train_steps, learning_rate=train.learning_rate * loop.fine_tune_learning_rate_factor,
        lr_schedule="constant", lr_warmup_steps=0, energy_warmup_fraction=0.0,
    )  # fmt: skip
