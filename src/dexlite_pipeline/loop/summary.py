"""A round's summary (stage ``loop_summary``): its table per training object and its row of the loop table
(grasps, distinct grasps, candidates per reason, CPU seconds, the held-out check)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from dexlite_pipeline.evaluation.config import DiversityConfig
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store
from dexlite_pipeline.loop.round_basics import DROP_REASONS, TRAIN
from dexlite_pipeline.loop.round_objects import round_objects


def stores_cpu_seconds(paths: list[str]) -> float:
    """The CPU seconds the jobs that wrote the stores at ``paths`` recorded (attribute ``cpu_seconds``; 0 where absent)."""
    return float(sum(float(read_grasp_store(p).attrs.get("cpu_seconds") or 0.0) for p in paths))


def round_summary(
    round_number: int, set_path: str, heldout_paths: list[str], cost_paths: list[str], heldout_cost_paths: list[str], model_path: str | None,
    objects_dirs: list[str], stability_path: str, diversity: DiversityConfig,
) -> tuple[pd.DataFrame, dict]:
    """The round's table per training object and its one row of the loop table.

    Per stable training object: grasps and distinct grasps in the round's set (``set_path``), and the round's
    candidates sampled, kept and dropped per reason (none in round 0). The row: those per object (means over the
    training objects), the CPU seconds of the round's jobs (``cost_paths``' stores and the model's training;
    ``model_path`` None in round 0, whose set the pipeline's stages made), and the held-out check of the round's
    model (``heldout_paths``: validated held-out grasps): attempts, lift and six-direction success per attempt,
    distinct held grasps per held-out object, its CPU seconds (``heldout_cost_paths``).
    """
    from dexlite_pipeline.evaluation.metrics import per_object_diversity

    grasps = read_grasp_store(set_path)
    object_ids = round_objects(objects_dirs, stability_path, 0, 1, TRAIN)[0]
    counts = per_object_diversity(grasps.arrays, np.ones(len(grasps), bool), diversity) if len(grasps) else {}
    candidates = pd.DataFrame(grasps.attrs.get("candidates") or [], columns=["object_id", "sampled", "kept", *DROP_REASONS]).set_index("object_id")
    rows = []
    for object_id in sorted(set(object_ids) | set(counts)):
        row = {"object_id": object_id, "grasps": counts.get(object_id, {}).get("held", 0), "distinct_grasps": counts.get(object_id, {}).get("distinct", 0)}
        row.update({k: int(candidates.loc[object_id, k]) if object_id in candidates.index else 0 for k in ("sampled", "kept", *DROP_REASONS)})
        rows.append(row)
    table = pd.DataFrame(rows, columns=["object_id", "grasps", "distinct_grasps", "sampled", "kept", *DROP_REASONS])
    cpu = stores_cpu_seconds(cost_paths)
    model_steps = None
    if model_path is not None:
        from dexlite_pipeline.model.checkpoint import load_checkpoint

        checkpoint = load_checkpoint(model_path)[1]
        cpu += float(checkpoint.get("cpu_seconds") or 0.0)
        model_steps = checkpoint.get("steps")
    summary = {
        "round": int(round_number),
        "training_objects": len(table),
        "objects_without_grasps": int((table["grasps"] == 0).sum()),
        "grasps": int(table["grasps"].sum()),
        "grasps_per_object": float(table["grasps"].mean()) if len(table) else float("nan"),
        "distinct_per_object": float(table["distinct_grasps"].mean()) if len(table) else float("nan"),
        "distinct_min": int(table["distinct_grasps"].min()) if len(table) else 0,
        **{k: int(table[k].sum()) for k in ("sampled", "kept", *DROP_REASONS)},
        "model_steps": model_steps,
        "cpu_seconds": cpu if round_number > 0 else float("nan"),
        **heldout_check([read_grasp_store(p) for p in heldout_paths], diversity),
        "heldout_cpu_seconds": stores_cpu_seconds(heldout_cost_paths),
    }
    return table, summary


def heldout_check(validated: list[GraspSet], diversity: DiversityConfig) -> dict:
    """Attempts, lift and six-direction success per attempt (a grasp not refined counts as a failure) and distinct
    held grasps per held-out object (objects with attempts, one without a held grasp counting 0) of a held-out check."""
    from dexlite_pipeline.evaluation.metrics import per_object_diversity

    stores = [v for v in validated if len(v)]
    if not stores:
        return {"heldout_objects": 0, "heldout_attempts": 0, "heldout_lift_success": float("nan"),
                "heldout_six_dir_success": float("nan"), "heldout_distinct_per_object": float("nan")}  # fmt: skip
    grasps = GraspSet.concatenate_common(stores)[0]
    held = np.asarray(grasps.arrays["lift_success"], bool)
    six = np.asarray(grasps.arrays["six_dir_success"], bool) if "six_dir_success" in grasps.arrays else np.zeros(len(grasps), bool)
    per_object = per_object_diversity(grasps.arrays, held, diversity)
    return {
        "heldout_objects": len(per_object),
        "heldout_attempts": len(grasps),
        "heldout_lift_success": float(held.mean()),
        "heldout_six_dir_success": float(six.mean()),
        "heldout_distinct_per_object": float(np.mean([v["distinct"] for v in per_object.values()])),
    }
