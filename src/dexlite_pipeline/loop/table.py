"""The loop table (stage ``loop_table``, results/loop.csv): one row per round of the data loop."""

from __future__ import annotations

import pandas as pd

from dexlite_pipeline.loop.round_basics import DROP_REASONS

LOOP_TABLE_COLUMNS = (
    "round", "training_objects", "objects_without_grasps", "grasps", "grasps_per_object", "distinct_per_object", "distinct_min",
    "sampled", "kept", *DROP_REASONS, "model_steps", "cpu_seconds", "heldout_objects", "heldout_attempts", "heldout_lift_success",
    "heldout_six_dir_success", "heldout_distinct_per_object", "heldout_cpu_seconds",
)  # fmt: skip


def loop_table(rows: list[dict]) -> pd.DataFrame:
    """The loop table (results/loop.csv): one row per round (``summary.round_summary``), in round order."""
    return pd.DataFrame(sorted(rows, key=lambda r: r["round"]), columns=list(LOOP_TABLE_COLUMNS))
