"""The pretrained model that ships with the package: where it is and which objects it was trained on.

The model of the large run (``config/profiles/large.yaml``) is package data, in
``src/dexlite_pipeline/data/shadow-hand-large/`` beside its model card (``MODEL_CARD.md``,
``card.json``): a checkout, an editable install, ``pip install .`` and a wheel all have it. The
default run samples it as its own method rows (``shipped_raw`` / ``shipped_post``) on the
held-out objects it never trained on; ``dexlite grasp`` uses it when no model is given.
"""

from __future__ import annotations

import os
from pathlib import Path

# this file is dexlite_pipeline/model/shipped.py; the model is dexlite_pipeline/data/shadow-hand-large/cvae.pt
PACKAGE_DATA = Path(__file__).resolve().parents[1] / "data"
SHIPPED_MODEL_PATH = PACKAGE_DATA / "shadow-hand-large" / "cvae.pt"
# The same file as a path in a source checkout (config.yaml's sample.shipped_model, read by the workflow).
SHIPPED_MODEL_RELATIVE = Path("src") / "dexlite_pipeline" / "data" / "shadow-hand-large" / "cvae.pt"


def shipped_model_path() -> Path | None:
    """The shipped model file, or None when the package was installed without its data."""
    return SHIPPED_MODEL_PATH if SHIPPED_MODEL_PATH.is_file() else None


def model_or_shipped(model: str | os.PathLike | None) -> Path:
    """``model`` when given, else the shipped model; a clear error when neither exists."""
    if model:
        return Path(model)
    shipped = shipped_model_path()
    if shipped is None:
        raise FileNotFoundError(
            f"no --model given and no shipped model at {SHIPPED_MODEL_PATH} (the package was installed without its data)"
        )
    return shipped


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

    ``config`` is the typed tree (``settings.PipelineConfig``) of the run that made the model.
    Deterministic for a given seed and thread count; across machines the lift outcomes of a
    few grasps may flip, so compare with sampling noise in mind.
    """
    import dataclasses

    import numpy as np
    import torch

    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.model.checkpoint import cloud_reading, load_checkpoint
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.pose import pose_errors
    from dexlite_pipeline.model.sampling import SHIPPED_SYNTHESIS, ladder_rows, synthesis_rows
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.sim.results import lift_grasp_set

    if not train_ids or not heldout_ids:
        raise ValueError(f"the check needs training and held-out objects (got {len(train_ids)} and {len(heldout_ids)})")
    model, checkpoint = load_checkpoint(model_path, "cpu")
    points, fixed = cloud_reading(checkpoint)
    clouds = ObjectClouds([load_asset(objects_dirs, oid) for oid in [*train_ids, *heldout_ids]])
    generator = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        reconstructions = ladder_rows(
            model, checkpoint["training_grasps"], clouds, list(train_ids), dataclasses.replace(config.sample, synthesis_grasps_per_object=0, ladder_grasps_per_object=0),
            points, generator, ShadowHand(), fixed,
        )  # fmt: skip
        rotation, translation, joints = pose_errors(reconstructions.hand_pose.cpu(), torch.as_tensor(reconstructions.reference_pose))
        settings = dataclasses.replace(config.sample, synthesis_grasps_per_object=grasps_per_object)
        samples = synthesis_rows(model, clouds, list(heldout_ids), settings, points, generator, fixed, SHIPPED_SYNTHESIS)
    grasps = GraspSet({
        "hand_pose": samples.hand_pose.cpu().numpy(), "object_id": np.asarray(samples.object_id, dtype=object), "scale": np.asarray(samples.scale, np.float32),
    })  # fmt: skip
    tested, _ = lift_grasp_set(grasps, objects_dirs, config.lift, threads)
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
