"""On-generator examples for the grasp evaluator (stage ``evaluator_examples``, one shard).

The evaluator ranks the model's raw samples by how likely they hold after post-optimization, so its
most telling examples are those very samples with that outcome: the trained model's pure syntheses on
the shard's stable *training* objects (``evaluator.examples_per_object`` each, drawn as the evaluation
draws them on held-out objects), post-optimized as the evaluation refines them, and every one of them
lift- and six-direction-tested (on each object's table in tabletop mode). Held-out objects never enter.
"""

from __future__ import annotations

import dataclasses
import logging
import tempfile
import time
from pathlib import Path

import numpy as np

from dexlite_pipeline.io.grasp_store import GRASP_TYPE, GraspSet

log = logging.getLogger(__name__)

EXAMPLE_METHOD = "cvae_examples"  # method label of the on-generator examples


def example_syntheses(
    model_path: str, objects_dirs: list[str], stability_path: str, shard: int, shard_count: int, per_object: int, sample, seed: int,
    device: str, hand: str = "shadow", table: bool = False,
) -> tuple[GraspSet, dict]:
    """``per_object`` pure syntheses of the model at ``model_path`` on each stable training object of ``shard``; the
    model must be of ``hand`` (config key ``hand``), and the attributes record the hand. ``table`` (scene.table): the
    model reads each cloud in its table frame (``model.table_frame``).

    ``sample`` is the ``SampleConfig`` (scales, latent prior, associated points: as the evaluation's ``cvae_raw``).
    Returns the grasps (hand_pose, object_id, scale, method) and attributes (objects left out, with why; seconds per grasp).
    """
    import torch

    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.hand.choice import hand_record
    from dexlite_pipeline.loop.round_basics import TRAIN
    from dexlite_pipeline.loop.round_objects import round_objects
    from dexlite_pipeline.model.checkpoint import cloud_reading, load_checkpoint
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.sampling import synthesis_rows
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.sharding import shard_generator
    from dexlite_pipeline.tabletop import load_support_planes

    started = time.process_time()
    device = resolve_device(device)
    record = hand_record(hand)
    model, checkpoint = load_checkpoint(model_path, device, hand=record)
    points, fixed_clouds = cloud_reading(checkpoint, sample.points_per_cloud)
    object_ids, skipped = round_objects(objects_dirs, stability_path, shard, shard_count, TRAIN)
    arrays = {"hand_pose": np.zeros((0, model.pose_width), np.float32), "object_id": np.zeros(0, dtype=object), "scale": np.zeros(0, np.float32),
              "method": np.zeros(0, dtype=object), GRASP_TYPE: np.zeros(0, dtype=object)}
    if object_ids and per_object > 0:
        clouds = ObjectClouds([load_asset(objects_dirs, oid) for oid in object_ids], model.codes_mu.device,
                              load_support_planes(table, stability_path))
        generator = shard_generator("evaluator_examples", seed, shard)
        with torch.no_grad():
            rows = synthesis_rows(model, clouds, object_ids, sample, points, generator, fixed_clouds, EXAMPLE_METHOD, per_object)
        arrays = {"hand_pose": rows.hand_pose.cpu().numpy(), "object_id": np.asarray(rows.object_id, dtype=object),
                  "scale": np.asarray(rows.scale, np.float32), "method": np.asarray(rows.method, dtype=object),
                  GRASP_TYPE: np.asarray(rows.types(), dtype=object)}
    seconds = time.process_time() - started
    attrs = {**record, "stage": "evaluator_examples_sample", "shard": f"{shard:03d}", "model": str(model_path), "skipped_objects": skipped,
             "seconds_per_grasp": seconds / len(arrays["hand_pose"]) if len(arrays["hand_pose"]) else None}
    log.info("evaluator examples, shard %03d: %d syntheses on %d training objects", shard, len(arrays["hand_pose"]), len(object_ids))
    return GraspSet(arrays, {}), attrs


def collect_examples(
    model_path: str, objects_dirs: list[str], stability_path: str, shard: int, config, threads: int = 1
) -> GraspSet:
    """The shard's on-generator examples: syntheses (``example_syntheses``), refined (``optim.post_shard``, the
    ``post_optimize`` section without the random baseline) and simulated, every refined grasp (``loop.validate_round``
    with ``simulate_all``: ``lift_success``, ``six_dir_success``, ``raw_hand_pose`` the sampled pose).

    ``config`` is the ``PipelineConfig`` (sections seed, device, shards, hand, sample, post_optimize, scene,
    curate.thresholds, energy, lift, evaluator): every step uses the hand's model (the lift test its own scene). The store's attributes record the config it read and the CPU seconds of each step.
    """
    from dexlite_pipeline.config import json_ready
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.hand.choice import SHADOW, resolve_hand
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.loop.validate_round import validate_round
    from dexlite_pipeline.optim.post_shard import post_optimize_shard
    from dexlite_pipeline.tabletop import load_support_planes

    clock = time.process_time()
    sampled, sample_attrs = example_syntheses(
        model_path, objects_dirs, stability_path, shard, config.shards, config.evaluator.examples_per_object, config.sample, config.seed,
        config.device, config.hand, config.scene.table,
    )
    cpu = {"sample": time.process_time() - clock}
    post_optimize = dataclasses.replace(config.post_optimize, random_baseline=False)
    with tempfile.TemporaryDirectory(prefix="evaluator_examples_") as scratch:
        sample_path, post_path = str(Path(scratch) / "sample.zarr"), str(Path(scratch) / "post.zarr")
        write_grasp_store(sample_path, sampled, sample_attrs)
        clock = time.process_time()
        (refined, post_attrs), _ = post_optimize_shard(
            sample_path, objects_dirs, shard, post_optimize=post_optimize, self_penetration_margin_m=config.energy.self_penetration_margin_m,
            scene=config.scene, seed=_post_seed(config.seed), device=config.device, stability_path=stability_path, hand=config.hand,
        )
        write_grasp_store(post_path, refined, post_attrs)
        cpu["post_optimize"] = time.process_time() - clock
        clock = time.process_time()
        planes = load_support_planes(config.scene.table, stability_path)
        simulated = validate_round(
            post_path, objects_dirs, config.curate.thresholds, config.energy.weights, config.lift, True, threads, planes,
            str(resolve_device(config.device)), simulate_all=True,
            hand=None if config.hand == SHADOW else resolve_hand(config.hand, resolve_device(config.device)),
        )
        cpu["simulate"] = time.process_time() - clock
    held = np.asarray(simulated.arrays.get("lift_success", np.zeros(0)), bool)
    log.info("evaluator examples, shard %03d: %d simulated, %d held (%.1f%%); CPU s %s", shard, len(held), int(held.sum()),
             100.0 * held.mean() if len(held) else 0.0, {k: round(v, 1) for k, v in cpu.items()})
    attrs = {
        **simulated.attrs, "stage": "evaluator_examples", "shard": f"{shard:03d}", "model": str(model_path),
        "skipped_objects": sample_attrs["skipped_objects"], "cpu_seconds_by_step": cpu,
        "config": {"seed": config.seed, "sample": json_ready(config.sample), "post_optimize": json_ready(post_optimize),
                   "evaluator": json_ready(config.evaluator), "lift": json_ready(config.lift)},
    }
    return GraspSet(simulated.arrays, attrs)


def _post_seed(seed: int) -> int:
    """The post-optimization's seed for the examples: a stream apart from the post_optimize stage's for the same shard."""
    return int(seed) * 1_000_003 + 424_243
