"""A round's training settings: the previous model fine-tuned."""

from __future__ import annotations

import dataclasses

import pytest

from dexlite_pipeline.loop.config import LoopConfig
from dexlite_pipeline.loop.train_round import round_training_config
from dexlite_pipeline.model.config import TrainConfig


def test_a_round_fine_tunes_at_a_lower_constant_rate_with_no_warm_up():
    train = TrainConfig(learning_rate=2e-3, lr_schedule="cosine", lr_warmup_steps=200, energy_warmup_fraction=0.3, max_steps=8000)
    tuned = round_training_config(train, LoopConfig(train_steps=500, fine_tune_learning_rate_factor=0.1))
    assert tuned.max_steps == 500 and tuned.learning_rate == pytest.approx(2e-4)
    assert tuned.lr_schedule == "constant" and tuned.lr_warmup_steps == 0 and tuned.energy_warmup_fraction == 0.0
    assert dataclasses.replace(tuned, max_steps=8000, learning_rate=2e-3, lr_schedule="cosine", lr_warmup_steps=200,
                               energy_warmup_fraction=0.3) == train  # nothing else changes  # fmt: skip
