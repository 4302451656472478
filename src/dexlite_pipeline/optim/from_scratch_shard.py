"""Optimization from scratch for one shard of objects: the ``optimize_grasps`` stage's work.

The stable, prepared objects are dealt to shards (``sharding.shard_objects``); objects whose
asset cannot be used, or whose SDF grid differs from the shard's, are recorded with their
reason; the rest get grasps from ``optim.from_scratch.synthesize``.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np

from dexlite_pipeline.energy.grasp_energy import TERM_NAMES
from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.optim.from_scratch import synthesize
from dexlite_pipeline.tabletop import load_support_planes, store_arrays, store_attrs

if TYPE_CHECKING:
    from dexlite_pipeline.energy.config import EnergyConfig
    from dexlite_pipeline.optim.config import OptimizeGraspsConfig
    from dexlite_pipeline.sim.config import SceneConfig

log = logging.getLogger(__name__)


def empty_optimized_grasps(table: bool = False, width: int | None = None) -> GraspSet:
    """A zero-row shard with every array ``synthesize`` writes (dtypes and trailing shapes alike; ``table``: tabletop mode's too;
    ``width``: numbers per pose, None for the Shadow Hand's 28).

    A shard without usable objects must still carry the energy arrays: curation keeps only
    the arrays all its inputs have, and E_fc, E_dis and E_pen are what it filters on.
    """
    from dexlite_pipeline.energy.grasp_energy import CONTACT_COUNT
    from dexlite_pipeline.hand.model import POSE_DIM
    from dexlite_pipeline.io.grasp_store import empty_grasp_set

    width = POSE_DIM if width is None else width
    grasps = empty_grasp_set()
    grasps.arrays["hand_pose"] = np.zeros((0, width), np.float32)
    grasps.arrays["init_pose"] = np.zeros((0, width), np.float32)
    grasps.arrays["contact_index"] = np.zeros((0, CONTACT_COUNT), np.int16)
    for name in ("acceptance_rate", "penetration_mm", "contact_distance_mm", "E_total", *TERM_NAMES):
        grasps.arrays[name] = np.zeros(0, np.float32)
    grasps.arrays["passes_energy_thresholds"] = np.zeros(0, bool)
    grasps.arrays["stopped_at_iteration"] = np.zeros(0, np.int32)
    grasps.arrays["grasp_type"] = np.zeros(0, dtype=object)
    if table:
        grasps.arrays["E_table"] = np.zeros(0, np.float32)
        grasps.arrays.update(store_arrays(np.zeros((0, 3)), np.zeros(0)))
    return grasps


def real_size_scales(assets, settings: OptimizeGraspsConfig) -> list[tuple[float, ...]]:
    """Each object's scales with ``real_size``: its real scale once per configured scale (the same number of starts as the
    others) where it is known (``ObjectAsset.real_scale``), else the configured scales."""
    return [(a.real_scale,) * len(settings.scales) if a.real_scale else tuple(settings.scales) for a in assets]


def usable_assets(objects_dirs: list[str], object_ids: list[str], planes) -> tuple[list, dict[str, str]]:
    """The assets of ``object_ids`` that a shard can use together, and object id -> why not for the others: no resting
    pose in tabletop mode (``planes`` not None), an unreadable asset, or an SDF grid unlike the shard's (each logged)."""
    from dexlite_pipeline.objects.assets import ObjectAssetError, load_asset, split_by_sdf_grid

    assets, failed = [], {}
    for object_id in object_ids:
        if planes is not None and object_id not in planes:
            failed[object_id] = "no resting pose in the stability table (tabletop mode needs one)"
            continue
        try:
            assets.append(load_asset(objects_dirs, object_id))
        except ObjectAssetError as exc:
            failed[object_id] = f"asset unusable: {exc}"
    assets, set_aside = split_by_sdf_grid(assets)
    failed.update(set_aside)
    for object_id, reason in failed.items():
        log.warning("object %s skipped: %s", object_id, reason)
    return assets, failed


def optimize_shard(
    objects_dirs: list[str], stability_path: str, shard: int, *, shards: int, optimize_grasps: OptimizeGraspsConfig, energy: EnergyConfig,
    scene: SceneConfig, seed: int, device: str, skip_objects: set[str] | frozenset = frozenset(), hand: str = "shadow",
) -> tuple[GraspSet, dict]:
    """Optimized grasps of one shard: the stable, prepared objects dealt to ``shard`` of ``shards`` (train and held-out),
    but ``skip_objects`` (training objects whose grasps come from a grasp dataset; listed in ``objects_from_dataset``).

    The config sections it reads come as arguments: ``optimize_grasps``, ``energy``, ``scene``, and the
    top-level ``seed``, ``device`` and ``hand`` (``hand.choice``: the Shadow Hand's code path as before for ``shadow``,
    else the hand from its MJCF, power grasps only; the attributes record it, ``hand.choice.hand_record``).

    Returns the grasps and the store attributes: the settings used (with the scene mode), the objects
    synthesized, the objects that could not be used with their reason, and the run statistics. In
    tabletop mode (``scene.table``) each object's support plane comes from the stability table; a
    stable object without one is recorded as unusable.
    """
    from dexlite_pipeline.config import json_ready
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.hand.choice import hand_record, resolve_hand
    from dexlite_pipeline.objects.assets import ok_object_ids
    from dexlite_pipeline.optim.from_scratch import pose_width
    from dexlite_pipeline.objects.stability import stable_object_ids
    from dexlite_pipeline.sharding import shard_generator, shard_objects

    settings = optimize_grasps
    device = resolve_device(device)
    record = hand_record(hand)  # refuses an unusable hand (one line) before any work
    hand_model = resolve_hand(hand, device)
    object_ids = shard_objects(sorted(ok_object_ids(objects_dirs) & stable_object_ids(stability_path)), shard, shards)
    from_dataset = [oid for oid in object_ids if oid in skip_objects]
    object_ids = [oid for oid in object_ids if oid not in skip_objects]
    planes = load_support_planes(scene.table, stability_path)
    assets, failed = usable_assets(objects_dirs, object_ids, planes)
    log.info(
        "shard %03d: %d stable objects (%d usable), %d grasps each (%d scales), %d iterations, device %s",
        shard, len(object_ids), len(assets), settings.grasps_per_object * len(settings.scales), len(settings.scales),
        settings.annealing.iterations, device,
    )
    object_scales = real_size_scales(assets, settings) if settings.real_size else None
    if assets:
        grasps, stats = synthesize(assets, settings, energy, shard_generator("optimize_grasps", seed, shard), device, support_planes=planes,
                                   object_scales=object_scales, hand=hand_model)
    else:
        grasps, stats = empty_optimized_grasps(planes is not None, pose_width(hand_model)), {"grasps": 0, "passing": 0, "pass_fraction": 0.0, "stopped_early": 0,
                                                                     "grasp_types": {}, "seconds": 0.0, "seconds_per_grasp": 0.0}
    attrs = {
        "stage": "optimize_grasps",
        "shard": f"{shard:03d}",
        "seed": seed,
        **record,
        "config": {"optimize_grasps": json_ready(settings), "energy": json_ready(energy), "scene": json_ready(scene), "hand": hand},
        **store_attrs(scene.table),
        "objects": [a.object_id for a in assets],
        "objects_at_real_size": [a.object_id for a in assets if settings.real_size and a.real_scale],
        "failed_objects": failed,
        "objects_from_dataset": from_dataset,
        **stats,
        "passing_per_hour": stats["passing"] / stats["seconds"] * 3600 if stats["seconds"] else 0.0,
    }
    return grasps, attrs
