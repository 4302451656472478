"""Stage ``train_evaluator``'s work: a grasp evaluator trained on every simulated grasp of a run's training objects.

Two sources: the lift-validated shards (optimization's curated grasps, mostly held) and the on-generator examples
(``evaluator.examples``: the trained model's syntheses, refined and simulated, about a third held). Each grasp is
an example of the pose the evaluator will be asked about: the sampled pose, before post-optimization, for the
on-generator examples (``raw_hand_pose``), the stored pose for optimization's grasps (which post-optimization would
start from). Only the catalogs' training objects enter, whatever the stores hold: a held-out object's grasps
never reach the training set (tests/evaluator/test_evaluator_training.py, and the tiny run's tests/workflow/test_evaluator_run.py). Grasps never simulated are left out with
their reason (``EvaluatorExamples.excluded``).
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace

import numpy as np

from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store

log = logging.getLogger(__name__)

NOT_OPTIMIZED = "not_optimized"  # loop.round_basics' drop reason of a sample post-optimization could not start from


def as_examples(grasps: GraspSet) -> GraspSet:
    """A simulated store as the evaluator sees it: a post-optimized sample's pose is its sampled pose (``raw_hand_pose``),
    and a sample that was never refined (``drop_reason`` not_optimized) is marked never simulated."""
    arrays = dict(grasps.arrays)
    if "raw_hand_pose" in arrays:
        arrays["hand_pose"] = np.asarray(arrays["raw_hand_pose"], np.float32)
    if "drop_reason" in arrays:
        failure = np.asarray(arrays.get("failure_reason", np.full(len(grasps), "", dtype=object)), dtype=object).copy()
        never = np.asarray([str(r) == NOT_OPTIMIZED for r in arrays["drop_reason"]], dtype=bool)
        failure[never] = "not_tested: post-optimization could not start from it"
        arrays["failure_reason"] = failure
    return GraspSet(arrays, grasps.attrs)


def train_from_run(
    lift_paths: list[str], example_paths: list[str], objects_dirs: list[str], section, seed: int, device: str, hand: str = "shadow"
) -> tuple[object, dict]:
    """(evaluator, facts) trained on the run's simulated grasps of its training objects; ``section`` is ``EvaluatorSection``,
    ``hand`` config key ``hand`` (every store must be of it: ``GraspStoreError`` in one line naming one that is not).

    The facts (JSON-ready) name the training objects, the examples per source and what was left out, the training
    history and the validation AUC; they go into the evaluator file and its JSON beside it.
    """
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.model.evaluator import EvaluatorConfig, evaluator_examples, train_evaluator
    from dexlite_pipeline.model.hand_match import shards_hand
    from dexlite_pipeline.objects.assets import object_splits

    started = time.process_time()
    training_ids = {oid for oid, split in object_splits(objects_dirs).items() if split == "train"}
    sources = {"optimization": [read_grasp_store(p) for p in lift_paths], "on_generator": [as_examples(read_grasp_store(p)) for p in example_paths]}
    shards_hand([(path, store.attrs) for path, store in zip([*lift_paths, *example_paths], [*sources["optimization"], *sources["on_generator"]])], hand)
    counts = {}
    for name, stores in sources.items():
        grasps = [g for g in stores if len(g)]
        inside = [np.isin(g.object_id.astype(str), sorted(training_ids)) for g in grasps]
        held = [np.asarray(g.arrays.get("lift_success", np.zeros(len(g))), bool) for g in grasps]
        counts[name] = {"grasps": int(sum(len(g) for g in grasps)), "on_training_objects": int(sum(m.sum() for m in inside)),
                        "held_on_training_objects": int(sum((h & m).sum() for h, m in zip(held, inside)))}
    examples = evaluator_examples([*sources["optimization"], *sources["on_generator"]], objects_dirs, training_ids)
    config = EvaluatorConfig(epochs=section.epochs, hand_points_per_shape=section.hand_points_per_shape,
                             validation_fraction=section.validation_fraction, rotation_augmentation=section.rotation_augmentation,
                             seed=int(seed))
    available = examples.clouds.samples_per_object  # small runs prepare fewer surface samples than the default cloud
    if available < config.points_per_cloud:
        log.info("evaluator clouds: %d points (the objects hold %d surface samples)", available, available)
        config = replace(config, points_per_cloud=available, pointnet_points=min(config.pointnet_points, available))
    model, history = train_evaluator(examples, config, resolve_device(device), hand)
    best = next((row for row in history.epochs if row["epoch"] == history.best_epoch), {})
    facts = {
        "train_object_ids": sorted(set(examples.object_id.tolist())),
        "fit_object_ids": history.train_object_ids, "validation_object_ids": history.validation_object_ids,
        "examples": int(len(examples)), "held": int(examples.held.sum()), "excluded": examples.excluded, "sources": counts,
        "best_epoch": history.best_epoch, "validation_auc_held": best.get("val_auc_held"), "validation_auc_six_dir": best.get("val_auc_six_dir"),
        "pos_weight": history.pos_weight, "history": history.epochs, "cpu_seconds": time.process_time() - started,
    }
    log.info("evaluator: %d examples (%d held) on %d training objects; best epoch %d, validation AUC held %s", len(examples),
             int(examples.held.sum()), len(facts["train_object_ids"]), history.best_epoch, best.get("val_auc_held"))
    return model, facts
