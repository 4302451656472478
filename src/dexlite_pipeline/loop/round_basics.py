"""What every step of a data-loop round shares: the object parts a round samples on, the reasons a candidate
is not kept, each step's random seed and a job's own CPU seconds."""

from __future__ import annotations

import os

TRAIN, HELDOUT = "train", "heldout"  # the object splits a round samples on (``PARTS``)
PARTS = (TRAIN, HELDOUT)
# Why a sampled grasp is not added to the set, in the order the checks run ("" = kept).
NOT_OPTIMIZED = "not_optimized"  # the post-optimization could not run on it (invalid pose, no asset or resting pose)
ENERGY_FILTER = "energy_filter"  # above a threshold of the equal energy filter
LIFT_TEST = "lift_test"  # dropped or not lifted in the lift test
SIX_DIRECTIONS = "six_directions"  # held in the lift test, moved in the six-direction test
DUPLICATE = "duplicate"  # the same grasp (diversity definition) as one already in the set or picked earlier this round
DROP_REASONS = (NOT_OPTIMIZED, ENERGY_FILTER, LIFT_TEST, SIX_DIRECTIONS, DUPLICATE)


def round_seed(seed: int, round_number: int, shard: int = 0, part: str = TRAIN) -> int:
    """The random seed of one round's step on one shard: a different stream per round, shard and part, none of
    them the global ``seed`` itself (round 0's training and sampling use that)."""
    return int(seed) * 1_000_003 + 104_729 * (int(round_number) + 1) + 7919 * int(shard) + (0 if part == TRAIN else 613)


def process_cpu_seconds() -> float:
    """CPU seconds (user + system) this process and its finished children have used so far: a job's own cost."""
    times = os.times()
    return float(times.user + times.system + times.children_user + times.children_system)
