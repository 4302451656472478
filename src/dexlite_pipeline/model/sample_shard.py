"""CVAE grasps for one shard of objects: the ``sample_grasps`` stage's work.

Held-out objects get pure synthesis (method ``cvae_raw``); training objects get dataset
expansion from their lift-validated grasps (``cvae_expand_latent`` / ``cvae_expand_point``)
and, with ``sample.ladder``, the learning ladder's rows (``cvae_recon``: reconstructions of
the grasps the model was trained on; ``cvae_prior_train``: pure synthesis on training
objects). Objects are dealt to shards as in the other grasp stages (``sharding.shard_objects``
over the stable objects of the catalogs). Objects that get no grasps are listed with their
reason in the ``skipped_objects`` attribute.
"""

from __future__ import annotations

import logging
import time
from typing import TYPE_CHECKING

import numpy as np
import torch

from dexlite_pipeline.io.grasp_store import GRASP_TYPE, GraspSet, grasp_types, read_grasp_store
from dexlite_pipeline.model.methods import EXPAND_LATENT, EXPAND_POINT, SYNTHESIS
from dexlite_pipeline.model.sampling import SampledRows
from dexlite_pipeline.model.type_condition import GraspTypeRequestError, refusal, type_codes

if TYPE_CHECKING:
    from dexlite_pipeline.model.config import SampleConfig

log = logging.getLogger(__name__)


def known_grasps(paths: list[str], object_ids: set[str], hand: str = "shadow") -> GraspSet:
    """Lift-successful grasps with finite poses of ``object_ids`` from the lift shards (the grasps to expand), with their
    types; the shards must be of hand ``hand`` (config key ``hand``, ``model.trainer.read_lift_shards``)."""
    from dexlite_pipeline.model.hand_match import shards_hand

    sets, named_attrs = [], []
    for path in paths:
        grasps = read_grasp_store(path)
        named_attrs.append((path, grasps.attrs))
        if not len(grasps):
            continue
        keep = np.asarray(grasps.arrays["lift_success"], bool) & np.isin(grasps.object_id.astype(str), list(object_ids))
        keep &= np.isfinite(grasps.hand_pose).all(axis=1)
        sets.append(GraspSet({**{k: grasps.arrays[k][keep] for k in ("hand_pose", "object_id", "scale")}, GRASP_TYPE: grasp_types(grasps)[keep]}, {}))
    shards_hand(named_attrs, hand)
    return GraspSet.concatenate(sets)


def expansion_picks(to_expand: GraspSet, per_object: int) -> np.ndarray:
    """The rows of ``to_expand`` that are expanded: ``per_object`` per object (sorted by id), cycling through its grasps in order."""
    object_ids = sorted(set(to_expand.object_id.tolist()))
    return np.concatenate([
        np.flatnonzero(to_expand.object_id == oid)[np.arange(per_object) % int((to_expand.object_id == oid).sum())]
        for oid in object_ids
    ]) if object_ids else np.zeros(0, np.int64)


def shard_targets(
    objects_dirs: list[str], stability_path: str, lift_paths: list[str], shard: int, shard_count: int, model_train_ids: set[str], ladder: bool,
    hand: str = "shadow",
) -> tuple[list[str], GraspSet, list[str], dict[str, str]]:
    """What the shard samples on: its held-out objects, the known grasps of its training objects
    (the grasps to expand), its training objects the model was fitted to (the ladder's, when
    ``ladder``), and the objects that get nothing, with why."""
    from dexlite_pipeline.objects.assets import available_object_ids, object_splits
    from dexlite_pipeline.objects.stability import stable_object_ids
    from dexlite_pipeline.sharding import shard_objects

    splits = object_splits(objects_dirs)
    ids = shard_objects(sorted(stable_object_ids(stability_path) & set(splits)), shard, shard_count)
    available = available_object_ids(objects_dirs)
    skipped = {oid: "no prepared asset" for oid in ids if oid not in available}
    ids = [oid for oid in ids if oid in available]
    heldout = [oid for oid in ids if splits[oid] == "heldout"]
    to_expand = known_grasps(lift_paths, {oid for oid in ids if splits[oid] == "train"}, hand)
    expandable = set(to_expand.object_id.tolist())
    skipped.update({oid: "training object without lift-validated grasps to expand" for oid in ids if splits[oid] == "train" and oid not in expandable})
    ladder_ids = sorted(oid for oid in ids if splits[oid] == "train" and oid in model_train_ids) if ladder else []
    return heldout, to_expand, ladder_ids, skipped


def shipped_rows(
    shipped_path: str, heldout: list[str], clouds, settings, generator: torch.Generator, device, hand_record: dict | None = None
) -> tuple:
    """Pure syntheses of the shipped (pretrained) model on the held-out objects it never trained on.

    Returns the rows (``SampledRows`` or None) and the held-out objects left out, with why:
    an object in the shipped model's training set would measure recall, not generalization, and none is sampled
    when ``sample.grasp_type`` asks for a type the shipped model does not know, or when the run's hand (``hand_record``;
    None: any) is not the shipped model's (the shipped model is the Shadow Hand's).
    """
    from dexlite_pipeline.model.checkpoint import cloud_reading, load_checkpoint
    from dexlite_pipeline.model.hand_match import hand_mismatch, recorded_hand
    from dexlite_pipeline.model.methods import SHIPPED_SYNTHESIS
    from dexlite_pipeline.model.sampling import synthesis_rows

    model, checkpoint = load_checkpoint(shipped_path, device)
    other_hand = hand_mismatch(shipped_path, recorded_hand(checkpoint), hand_record) if hand_record is not None else ""
    if other_hand:
        log.warning("%s; its rows are not sampled", other_hand)
        return None, {oid: f"sample.shipped_model: {other_hand}" for oid in heldout}
    trained_on = set(checkpoint.get("train_object_ids") or [])
    unseen = [oid for oid in heldout if oid not in trained_on]
    left_out = {oid: "the shipped model was trained on it" for oid in heldout if oid in trained_on}
    reason = refusal(model.type_vocabulary, settings.grasp_type)
    if reason:
        log.warning("%s: %s; its rows are not sampled", shipped_path, reason)
        return None, {**left_out, **{oid: f"sample.grasp_type: {reason}" for oid in unseen}}
    if not unseen or settings.synthesis_grasps_per_object <= 0:
        return None, left_out
    points, fixed = cloud_reading(checkpoint, settings.points_per_cloud)
    return synthesis_rows(model, clouds, unseen, settings, points, generator, fixed, SHIPPED_SYNTHESIS), left_out


def sample_shard(
    model_path: str, objects_dirs: list[str], stability_path: str, lift_paths: list[str], shard: int, *, shards: int,
    sample: SampleConfig, seed: int, device: str, shipped_model: str | None = None, hand: str = "shadow", table: bool = False,
) -> tuple[GraspSet, dict]:
    """Every CVAE grasp of ``shard``: syntheses on held-out objects, expansions and ladder rows on training objects
    and, with ``shipped_model`` (a pretrained model file), its syntheses on held-out objects (``shipped_rows``).

    Returns the grasps (``hand_pose``, ``object_id``, ``scale``, ``method``, ``grasp_type`` and, for ladder
    reconstructions, the ``reference_hand_pose`` they reproduce; NaN elsewhere) and the
    store attributes (with the hand's record: ``hand``, ``joint_names``). The config it reads comes as arguments: ``shards``,
    section ``sample``, ``seed``, ``device`` and ``hand`` (the model must be of that hand: ``CheckpointError`` in one line
    otherwise; the grasps to expand must be too), and ``table`` (scene.table: the model reads each cloud in its table frame,
    ``model.table_frame``, from the stability table's resting poses).
    Its ``seconds_per_grasp`` is the CPU time of the whole call (loading the model and the objects included) per row.
    """
    started = time.process_time()  # CPU seconds (all threads of this process), not wall time
    from dexlite_pipeline.config import json_ready
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.hand.choice import hand_record, resolve_hand
    from dexlite_pipeline.model.association import grasp_rays
    from dexlite_pipeline.model.checkpoint import cloud_reading, load_checkpoint
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.sampling import expand, ladder_rows, synthesis_rows
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.sharding import shard_generator
    from dexlite_pipeline.tabletop import load_support_planes

    settings = sample
    device = resolve_device(device)
    record = hand_record(hand)
    model, checkpoint = load_checkpoint(model_path, device, hand=record)
    if refusal(model.type_vocabulary, settings.grasp_type):
        raise GraspTypeRequestError(f"{model_path}: {refusal(model.type_vocabulary, settings.grasp_type)} (sample.grasp_type)")
    points, fixed_clouds = cloud_reading(checkpoint, settings.points_per_cloud)

    heldout, to_expand, ladder_ids, skipped = shard_targets(
        objects_dirs, stability_path, lift_paths, shard, shards, set(checkpoint.get("train_object_ids") or []), settings.ladder, hand
    )
    hand_model = resolve_hand(hand, device)
    expandable = set(to_expand.object_id.tolist())
    targets = sorted(set(heldout) | expandable | set(ladder_ids))
    generator = shard_generator("sample_grasps", seed, shard)
    parts: list[SampledRows] = []
    shipped_left_out: dict[str, str] = {}
    if targets:
        clouds = ObjectClouds([load_asset(objects_dirs, oid) for oid in targets], device, load_support_planes(table, stability_path))
        if heldout and settings.synthesis_grasps_per_object > 0:
            parts.append(synthesis_rows(model, clouds, heldout, settings, points, generator, fixed_clouds, SYNTHESIS))
        if len(to_expand) and settings.expansion_grasps_per_object > 0:
            pick = expansion_picks(to_expand, settings.expansion_grasps_per_object)
            known = torch.as_tensor(to_expand.hand_pose[pick], dtype=torch.float32, device=device)
            origin, direction = grasp_rays(hand_model, known)
            obj = np.array([clouds.index_of[o] for o in to_expand.object_id[pick]])
            scale = to_expand.scale[pick].astype(np.float32)
            move_point = torch.rand(len(pick), generator=generator) < settings.expansion_point_fraction
            types = to_expand.arrays[GRASP_TYPE][pick]
            pose = expand(model, clouds, known, origin, direction, obj, scale, move_point.to(device), settings, points, generator, fixed_clouds,
                          type_codes(types, model.type_vocabulary))
            methods = [EXPAND_POINT if m else EXPAND_LATENT for m in move_point.tolist()]
            parts.append(SampledRows(pose, [clouds.object_ids[i] for i in obj], scale, methods, grasp_type=[str(t) for t in types]))
        if ladder_ids and "training_grasps" in checkpoint:
            parts.append(ladder_rows(model, checkpoint["training_grasps"], clouds, ladder_ids, settings, points, generator, hand_model, fixed_clouds))
        elif ladder_ids:
            log.warning("%s: the model file holds no training grasps, so the learning ladder's rows are not sampled", model_path)
        if shipped_model and heldout:
            shipped, shipped_left_out = shipped_rows(shipped_model, heldout, clouds, settings, generator, device, record)
            parts += [shipped] if shipped is not None else []
    rows = SampledRows.concatenate(parts, device, model.pose_width)
    seconds = time.process_time() - started
    count = len(rows.method)
    arrays = {
        "hand_pose": rows.hand_pose.cpu().numpy(),
        "object_id": np.asarray(rows.object_id, dtype=object),
        "scale": rows.scale,
        "method": np.asarray(rows.method, dtype=object),
        GRASP_TYPE: np.asarray(rows.types(), dtype=object),
        # the known grasp each ladder reconstruction reproduces (NaN for other rows): the fit rung's pose errors
        "reference_hand_pose": rows.reference_pose,
    }
    attrs = {
        **record,
        "stage": "sample_grasps",
        "shard": f"{shard:03d}",
        "config": {"seed": seed, "sample": json_ready(settings), "points_per_cloud": points},
        "model_seed": checkpoint.get("seed"),
        "model_steps": checkpoint.get("steps"),
        "seconds_per_grasp": seconds / count if count else None,
        "skipped_objects": skipped,
        "shipped_model": str(shipped_model) if shipped_model else None,
        "shipped_skipped_objects": shipped_left_out,
    }
    log.info(
        "shard %03d: %d grasps (%d synthesized on %d held-out objects, %d others on %d training objects) in %.2fs; skipped %d objects",
        shard, count, rows.method.count(SYNTHESIS), len(heldout), count - rows.method.count(SYNTHESIS), len(expandable | set(ladder_ids)), seconds, len(skipped),
    )
    return GraspSet(arrays, {}), attrs
