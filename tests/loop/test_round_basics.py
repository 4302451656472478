"""What the steps of a round share: each step's random seed."""

from __future__ import annotations

from dexlite_pipeline.loop.round_basics import round_seed


def test_round_seeds_differ_by_round_shard_and_part_and_from_the_global_seed():
    seeds = {round_seed(0, r, s, p) for r in range(3) for s in range(2) for p in ("train", "heldout")}
    assert len(seeds) == 12 and 0 not in seeds
