"""A dataset batch made by the model, one shard of objects: the ``model_batch`` stage's work (section ``model_batch``).

Dex1B grows its data by letting the generator propose and the simulator keep what holds; optimization from scratch,
several times dearer per distinct held grasp where the model knows the shapes, is left for the objects where the
model falls short. For each stable object of the shard, at its real size (the household generator's metres; the
configured sample scales for an object without one):

1. the generator's ``grasps_per_object`` grasps: CVAE samples turned to the heading the model knows best
   (``sample.yaw_candidates``), ranked by the learned evaluator (the best distinct of ``evaluator.pool_factor`` x as
   many), refined by post-optimization on the object's table (``sample``, ``post_optimize``);
2. the lift test and the six-direction test of every one of them (``lift``, six directions always on: the dataset
   records both);
3. the top-up: each object with fewer than ``min_distinct`` distinct held grasps (``diversity``: palms within 2 cm
   and 30 deg are one grasp) gets batches of ``grasps_per_object`` grasps by optimization from scratch
   (``optimize_grasps``, its grasp types too), each tested as above, until it has them, ``top_up_batches``
   batches were tried, or a batch added it no distinct held grasp.

Every grasp is kept, held or not, with its ``source`` (``model`` or ``optimization``); the store's attributes hold
the sections used, the model and evaluator files with their SHA-256, the objects, those that could not be used with
the reason, the objects topped up, and the seconds of each phase. ``dexlite dataset-add`` reads it as a batch of
kind ``model``. The steps are those of ``dexlite grasp`` (``tools.grasp.synthesis``), on the pipeline's prepared
objects and resting poses instead of the user's meshes.

The hand is config key ``hand`` (docs/hands.md): the model and the evaluator must be of it (a file of another hand is
refused in one line naming the key and the file, before any work), and the samples' refinement, the top-up's
optimization from scratch and the lift and six-direction tests use its model and scene; poses are 6 + J numbers and
the store records the hand (``hand``, ``joint_names``, ``hand_sha256`` for an MJCF file) as the other stages' stores
do. The Shadow Hand's path is the one it always was (its hand model is the callees' own default).
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dexlite_pipeline.model.shipped import SHIPPED
from dexlite_pipeline.tools.grasp.request import SOURCE_MODEL, SOURCE_OPTIMIZATION
from dexlite_pipeline.tools.grasp.run import hopeless_optimizations
from dexlite_pipeline.tools.grasp.selection import distinct_labels, distinct_per_object
from dexlite_pipeline.tools.grasp.synthesis import synthesize_from_scratch, synthesize_with_model, top_up_seed, top_up_until_distinct

if TYPE_CHECKING:
    from dexlite_pipeline.io.config import ModelBatchConfig
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.settings import PipelineConfig

log = logging.getLogger("dexlite.model_batch")

NO_EVALUATOR = "none"


class ModelBatchError(ValueError):
    """A ``model_batch`` key names a file that is not there (one line, naming the key)."""


def generator_files(section: ModelBatchConfig, hand: str = "shadow") -> tuple[Path, Path | None]:
    """The model file and the evaluator file (None: samples not ranked) that ``section`` names (``shipped``: those
    shipped for ``hand``, config key ``hand``)."""
    from dexlite_pipeline.model.shipped import missing_shipped_model_reason, shipped_evaluator_path, shipped_model_path

    model = shipped_model_path(hand) if section.model == SHIPPED else Path(section.model)
    if model is None or not model.is_file():
        raise ModelBatchError(f"model_batch.model: {section.model!r}: " +
                              (missing_shipped_model_reason(hand) if section.model == SHIPPED else "no such model file"))
    if section.evaluator == NO_EVALUATOR:
        return model, None
    evaluator = shipped_evaluator_path(hand) if section.evaluator == SHIPPED else Path(section.evaluator)
    if evaluator is None or not evaluator.is_file():
        raise ModelBatchError(f"model_batch.evaluator: {section.evaluator!r}: no such evaluator file (give '{NO_EVALUATOR}' to not rank)")
    return model, evaluator


def file_sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes (which model made a batch)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def shard_seed(seed: int, shard: int) -> int:
    """Shard ``shard``'s seed: independent streams per shard, the same for a given config seed."""
    return int(np.random.SeedSequence([seed, shard]).generate_state(1)[0])


@dataclasses.dataclass
class PhaseSeconds:
    """Wall-clock seconds of a shard's phases (the CPU time is snakemake's benchmark of the whole job)."""

    model: float = 0.0
    model_tests: float = 0.0
    top_up: float = 0.0
    top_up_tests: float = 0.0
    top_up_batches: int = 0


def load_generator(model_file: Path, evaluator_file: Path | None, device, record: dict) -> tuple[tuple, tuple | None]:
    """The loaded model and evaluator (None: none) for a run of the hand ``record`` (``hand.choice.hand_record``);
    ``ModelBatchError`` in one line naming the key and the file when either is of another hand or unreadable."""
    from dexlite_pipeline.model.checkpoint import load_checkpoint
    from dexlite_pipeline.model.evaluator import load_evaluator

    try:
        loaded = load_checkpoint(str(model_file), device, hand=record)
    except ValueError as exc:
        raise ModelBatchError(f"model_batch.model: {exc}") from None
    if evaluator_file is None:
        return loaded, None
    try:
        return loaded, load_evaluator(str(evaluator_file), device, hand=record)
    except ValueError as exc:
        raise ModelBatchError(f"model_batch.evaluator: {exc}") from None


def model_batch_shard(objects_dirs: list[str], stability_path: str, shard: int, config: PipelineConfig, threads: int) -> tuple[GraspSet, dict]:
    """Every tested grasp of shard ``shard``'s stable objects (see the module docstring) and the store's attributes."""
    from dexlite_pipeline.config import json_ready
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.hand.choice import SHADOW, hand_record, resolve_hand
    from dexlite_pipeline.io.grasp_store import empty_grasp_set
    from dexlite_pipeline.objects.assets import ok_object_ids
    from dexlite_pipeline.objects.stability import stable_object_ids
    from dexlite_pipeline.optim.from_scratch_shard import usable_assets
    from dexlite_pipeline.sharding import shard_objects
    from dexlite_pipeline.sim.results import lift_grasp_set
    from dexlite_pipeline.tabletop import load_support_planes, store_attrs

    section = config.model_batch
    record = hand_record(config.hand)  # an unusable hand: one line before any work (and before its shipped model is sought)
    model_file, evaluator_file = generator_files(section, config.hand)
    device = resolve_device(config.device)
    loaded, evaluator = load_generator(model_file, evaluator_file, device, record)
    hand = None if config.hand == SHADOW else resolve_hand(config.hand, device)  # None: the callees' Shadow Hand, as before
    seed = shard_seed(config.seed, shard)
    object_ids = shard_objects(sorted(ok_object_ids(objects_dirs) & stable_object_ids(stability_path)), shard, config.shards)
    planes = load_support_planes(config.scene.table, stability_path)
    assets, failed = usable_assets(objects_dirs, object_ids, planes)
    scales = {a.object_id: (a.real_scale,) if a.real_scale else tuple(config.sample.scales) for a in assets}
    lift_config = dataclasses.replace(config.lift, six_directions=True)
    seconds = PhaseSeconds()

    def tested(grasps: GraspSet, source: str) -> GraspSet:
        result, _ = lift_grasp_set(grasps, objects_dirs, lift_config, threads, support_planes=planes, known_failures=hopeless_optimizations(grasps),
                                   hand=hand)
        result.arrays["source"] = np.full(len(result), source, dtype=object)
        return result

    def top_up_batch(chosen, batch: int) -> GraspSet:
        t = time.perf_counter()
        grasps = synthesize_from_scratch(chosen, scales, section.grasps_per_object, config, device, top_up_seed(seed, batch), planes, hand)
        seconds.top_up += time.perf_counter() - t
        log.info("shard %03d top-up batch %d: lift and six-direction tests of %d grasps on %d object(s)", shard, batch + 1, len(grasps), len(chosen))
        t = time.perf_counter()
        result = tested(grasps, SOURCE_OPTIMIZATION)
        seconds.top_up_tests += time.perf_counter() - t
        seconds.top_up_batches += 1
        return result

    log.info("shard %03d: %d stable objects (%d usable); %d grasps each from %s%s, top-up below %d distinct held (at most %d batches), "
             "hand %s, device %s", shard, len(object_ids), len(assets), section.grasps_per_object, model_file,
             f" ranked by {evaluator_file}" if evaluator_file else "", section.min_distinct, section.top_up_batches, config.hand, device)  # fmt: skip
    topped_up: list[str] = []
    if assets:
        t = time.perf_counter()
        grasps = synthesize_with_model(assets, scales, section.grasps_per_object, config, loaded, str(model_file), device, seed, planes, evaluator,
                                       hand)  # fmt: skip
        seconds.model = time.perf_counter() - t
        t = time.perf_counter()
        result = tested(grasps, SOURCE_MODEL)
        seconds.model_tests = time.perf_counter() - t
        if section.min_distinct > 0 and section.top_up_batches > 0:
            result, topped_up, short = top_up_until_distinct(assets, result, config, section.min_distinct, section.top_up_batches, top_up_batch)
            for asset in short:
                log.warning("shard %03d: %s has fewer than %d distinct held grasps after %d top-up batch(es)", shard, asset.object_id,
                            section.min_distinct, section.top_up_batches)  # fmt: skip
    else:
        result = empty_grasp_set(record)  # no usable object: no grasps, poses of the hand's width
    counts = distinct_per_object(result, distinct_labels(result, config)) if len(result) else {}
    attrs = {
        "stage": "model_batch", "shard": f"{shard:03d}", "seed": config.seed, "shard_seed": seed, **record,
        "config": {name: json_ready(getattr(config, name)) for name in
                   ("model_batch", "sample", "post_optimize", "evaluator", "optimize_grasps", "energy", "diversity", "scene")},
        "lift_config": lift_config.as_dict(), **store_attrs(config.scene.table),
        "model_file": str(model_file), "model_sha256": file_sha256(model_file),
        "evaluator_file": str(evaluator_file or ""), "evaluator_sha256": file_sha256(evaluator_file) if evaluator_file else "",
        "objects": [a.object_id for a in assets], "failed_objects": failed, "topped_up_objects": topped_up,
        "distinct_held_per_object": {k: int(v) for k, v in counts.items()},
        "seconds": dataclasses.asdict(seconds),
    }
    return result, attrs
