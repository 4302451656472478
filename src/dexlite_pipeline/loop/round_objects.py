"""The objects a round's step works on: one shard's stable prepared objects of one part (training or held out)."""

from __future__ import annotations

from dexlite_pipeline.loop.round_basics import PARTS


def round_objects(objects_dirs: list[str], stability_path: str, shard: int, shard_count: int, part: str) -> tuple[list[str], dict[str, str]]:
    """The shard's stable prepared objects of split ``part`` (dealt as in the other grasp stages), and those left out with why."""
    from dexlite_pipeline.objects.assets import available_object_ids, object_splits
    from dexlite_pipeline.objects.stability import stable_object_ids
    from dexlite_pipeline.sharding import shard_objects

    if part not in PARTS:
        raise ValueError(f"part {part!r} is not one of {', '.join(PARTS)}")
    splits = object_splits(objects_dirs)
    ids = shard_objects(sorted(stable_object_ids(stability_path) & set(splits)), shard, shard_count)
    available = available_object_ids(objects_dirs)
    mine = [oid for oid in ids if splits[oid] == part]
    return [oid for oid in mine if oid in available], {oid: "no prepared asset" for oid in mine if oid not in available}
