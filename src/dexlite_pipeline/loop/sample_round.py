"""A round's sampling (stage ``loop_sample``): grasps from a model on one shard's objects of one part.

Part ``train``: the round's candidates, ``loop.grasps_per_object`` per stable training object with the loop's own
associated points (``loop.anchor_rule``); part ``heldout``: the round's held-out check, ``loop.heldout_grasps_per_object``
per held-out object, sampled as the evaluation samples (``round_sample_settings``).
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from dexlite_pipeline.config import json_ready
from dexlite_pipeline.io.grasp_store import GRASP_TYPE, GraspSet
from dexlite_pipeline.loop.config import LoopConfig
from dexlite_pipeline.loop.round_basics import TRAIN, round_seed
from dexlite_pipeline.loop.round_objects import round_objects

log = logging.getLogger(__name__)

LOOP_METHOD = "cvae_loop"  # method label of the grasps a round samples on training objects


def round_sample_settings(sample, loop: LoopConfig, part: str):
    """(sample settings, grasps per object, method label) of a round's part: ``train`` samples ``loop.grasps_per_object``
    per object with the loop's own associated points (``loop.anchor_rule``, ``loop.match_candidates``), labelled
    ``LOOP_METHOD``; ``heldout`` ``loop.heldout_grasps_per_object`` by the ``sample`` section's rules as they are,
    labelled as the evaluation's pure synthesis (``cvae_raw``), so the held-out check measures what the evaluation does."""
    from dexlite_pipeline.model.methods import SYNTHESIS

    if part == TRAIN:
        settings = dataclasses.replace(sample, anchor_rule=loop.anchor_rule, match_candidates=loop.match_candidates)
        return settings, loop.grasps_per_object, LOOP_METHOD
    return sample, loop.heldout_grasps_per_object, SYNTHESIS


def sample_round(
    model_path: str, objects_dirs: list[str], stability_path: str, shard: int, shard_count: int, part: str, round_number: int,
    loop: LoopConfig, sample, device, seed: int, hand: str = "shadow", table: bool = False,
) -> tuple[GraspSet, dict]:
    """Grasps of one shard's objects of split ``part`` from the model at ``model_path`` (``sample``: the ``SampleConfig``).

    What each part samples: ``round_sample_settings``. The model must be of ``hand`` (config key ``hand``; refused in one
    line otherwise). ``table`` (scene.table): the model reads each cloud in its table frame (``model.table_frame``).
    Returns the grasps (hand_pose, object_id, scale, method; poses of 6 + J numbers) and the store attributes, which
    record the hand.
    """
    import torch

    from dexlite_pipeline.model.checkpoint import cloud_reading, load_checkpoint
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.sampling import SampledRows, synthesis_rows
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.tabletop import load_support_planes

    from dexlite_pipeline.hand.choice import hand_record

    record = hand_record(hand)
    model, checkpoint = load_checkpoint(model_path, device, hand=record)
    points, fixed_clouds = cloud_reading(checkpoint, sample.points_per_cloud)
    object_ids, skipped = round_objects(objects_dirs, stability_path, shard, shard_count, part)
    settings, count, label = round_sample_settings(sample, loop, part)
    generator = torch.Generator().manual_seed(round_seed(seed, round_number, shard, part))
    if object_ids and count > 0:
        clouds = ObjectClouds([load_asset(objects_dirs, oid) for oid in object_ids], model.codes_mu.device,
                              load_support_planes(table, stability_path))
        rows = synthesis_rows(model, clouds, object_ids, settings, points, generator, fixed_clouds, label, count)
    else:
        rows = SampledRows.concatenate([], model.codes_mu.device)
    pose = rows.hand_pose.cpu().numpy() if len(rows.method) else np.zeros((0, 6 + len(record["joint_names"])), np.float32)  # 6 + J
    arrays = {
        "hand_pose": pose,
        "object_id": np.asarray(rows.object_id, dtype=object),
        "scale": rows.scale,
        "method": np.asarray(rows.method, dtype=object),
        GRASP_TYPE: np.asarray(rows.types(), dtype=object),
    }
    attrs = {
        **record, "stage": "loop_sample", "round": int(round_number), "part": part, "shard": f"{shard:03d}", "model": str(model_path),
        "model_steps": checkpoint.get("steps"), "config": {"seed": seed, "loop": json_ready(loop), "sample": json_ready(settings)},
        "skipped_objects": skipped,
    }  # fmt: skip
    log.info("round %d %s shard %03d: %d grasps on %d objects from %s", round_number, part, shard, len(rows.method), len(object_ids), model_path)
    return GraspSet(arrays, {}), attrs
