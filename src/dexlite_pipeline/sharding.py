"""Deterministic assignment of objects to shards (object groups) for the grasp-heavy stages."""

from __future__ import annotations

from collections.abc import Iterable


def shard_objects(object_ids: Iterable[str], shard: int, shard_count: int) -> list[str]:
    """Objects of ``shard`` (0-based) out of ``shard_count``: sorted ids dealt round-robin.

    The same ids, count and shard always give the same group, on any machine.
    """
    if shard_count < 1 or not 0 <= shard < shard_count:
        raise ValueError(f"shard {shard} out of range for {shard_count} shards")
    ordered = sorted(set(str(o) for o in object_ids))
    return ordered[shard::shard_count]
