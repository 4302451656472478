"""Deterministic assignment of objects to shards (object groups), and each shard's random stream."""

from __future__ import annotations

from collections.abc import Iterable

# Random streams of the sharded stages: stream name -> the generator seed as a function of the
# global seed and the shard number. The constants are the ones the stages have always used, so
# that a given seed keeps reproducing the same grasps. A stream's name is only its key here: the
# formula alone makes its numbers, so a renamed stream keeps its grasps.
STREAM_SEEDS = {
    "optimize_grasps": lambda seed, shard: seed * 1_000_003 + 7919 * (shard + 1),
    "sample_grasps": lambda seed, shard: seed * 1000 + shard,
    "post_optimize": lambda seed, shard: seed * 1000 + shard + 500,
    "grasp_tool_post_optimize": lambda seed, shard: seed * 1000 + 77,
    "evaluator_examples": lambda seed, shard: seed * 1000 + shard + 700,  # the trained model's syntheses on training objects
    "evaluator_ranking": lambda seed, shard: seed * 1000 + shard + 900,  # the pool the ranked rows are chosen from
}


def shard_objects(object_ids: Iterable[str], shard: int, shard_count: int) -> list[str]:
    """Objects of ``shard`` (0-based) out of ``shard_count``: sorted ids dealt round-robin.

    The same ids, count and shard always give the same group, on any machine.
    """
    if shard_count < 1 or not 0 <= shard < shard_count:
        raise ValueError(f"shard {shard} out of range for {shard_count} shards")
    ordered = sorted(set(str(o) for o in object_ids))
    return ordered[shard::shard_count]


def shard_generator(stream: str, seed: int, shard: int):
    """A CPU ``torch.Generator`` for ``stream`` (a key of ``STREAM_SEEDS``) of ``shard`` under the global ``seed``."""
    import torch

    if stream not in STREAM_SEEDS:
        raise ValueError(f"unknown random stream {stream!r} (known: {', '.join(sorted(STREAM_SEEDS))})")
    return torch.Generator().manual_seed(STREAM_SEEDS[stream](int(seed), int(shard)))
