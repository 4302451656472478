"""The shipped model's check: its learning ladder on a few objects, as its model card quotes it.

Apart from ``model.shipped`` (where the model is), so that finding the model imports no
sampling or simulation code.
"""

from __future__ import annotations

import os


def shipped_model_check(
    model_path: str | os.PathLike,
    objects_dirs: list[str],
    train_ids: list[str],
    heldout_ids: list[str],
    config,
    grasps_per_object: int,
    threads: int = 1,
    seed: int = 0,
) -> dict:
    """The learning ladder of a model on a few objects, in a form a card can quote and a test can repeat.

    - fit: encoder-mean reconstructions of every training grasp (from the model file) on
      ``train_ids``: median palm rotation (deg) and translation (mm) errors, mean joint error (rad);
    - held-out raw: ``grasps_per_object`` pure syntheses on each of ``heldout_ids`` (scales dealt
      from ``config.sample.scales``), lift-tested with ``config.lift``: successes per object.

    ``config`` is the typed tree (``settings.PipelineConfig``) of the run that made the model. The hand is the one the
    model file records (``model.hand_match.recorded_hand``; a file without one: the Shadow Hand): its kinematics place
    the reconstructions and its scene lift-tests the syntheses (6 + J numbers per pose).
    Deterministic for a given seed and thread count; across machines the lift outcomes of a
    few grasps may flip, so compare with sampling noise in mind.
    """
    import dataclasses

    import numpy as np
    import torch

    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.hand.choice import SHADOW, resolve_hand
    from dexlite_pipeline.model.checkpoint import cloud_reading, load_checkpoint
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.hand_match import recorded_hand
    from dexlite_pipeline.model.pose import pose_errors
    from dexlite_pipeline.model.methods import SHIPPED_SYNTHESIS
    from dexlite_pipeline.model.sampling import ladder_rows, synthesis_rows
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.sim.results import lift_grasp_set

    if not train_ids or not heldout_ids:
        raise ValueError(f"the check needs training and held-out objects (got {len(train_ids)} and {len(heldout_ids)})")
    model, checkpoint = load_checkpoint(model_path, "cpu")
    record = recorded_hand(checkpoint)
    hand = None if record["hand"] == SHADOW else resolve_hand(record["hand"])  # None: the Shadow Hand, as before
    points, fixed = cloud_reading(checkpoint)
    clouds = ObjectClouds([load_asset(objects_dirs, oid) for oid in [*train_ids, *heldout_ids]])
    generator = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        reconstructions = ladder_rows(
            model, checkpoint["training_grasps"], clouds, list(train_ids), dataclasses.replace(config.sample, synthesis_grasps_per_object=0, ladder_grasps_per_object=0),
            points, generator, ShadowHand() if hand is None else hand, fixed,
        )  # fmt: skip
        rotation, translation, joints = pose_errors(reconstructions.hand_pose.cpu(), torch.as_tensor(reconstructions.reference_pose))
        settings = dataclasses.replace(config.sample, synthesis_grasps_per_object=grasps_per_object)
        samples = synthesis_rows(model, clouds, list(heldout_ids), settings, points, generator, fixed, SHIPPED_SYNTHESIS)
    grasps = GraspSet({
        "hand_pose": samples.hand_pose.cpu().numpy(), "object_id": np.asarray(samples.object_id, dtype=object), "scale": np.asarray(samples.scale, np.float32),
    }, {} if hand is None else record)  # fmt: skip
    tested, _ = lift_grasp_set(grasps, objects_dirs, config.lift, threads, hand=hand)
    success = np.asarray(tested.arrays["lift_success"], bool)
    per_object = {oid: int(success[tested.object_id == oid].sum()) for oid in heldout_ids}
    return {
        "fit": {
            "objects": list(train_ids), "grasps": len(rotation),
            "rotation_error_deg_median": float(rotation.median()), "translation_error_mm_median": float(translation.median()),
            "joint_error_rad_mean": float(joints.mean()),
        },
        "heldout_raw": {
            "objects": list(heldout_ids), "grasps_per_object": grasps_per_object, "grasps": len(success),
            "lift_successes": int(success.sum()), "lift_successes_per_object": per_object,
        },
    }  # fmt: skip
