"""The report's grasp-type table: per method (and split) and grasp type, the grasps tried, held and distinct held.

Shown only when the simulated grasps hold more than one type (``grasp_type``; a store without it holds power grasps,
``io.grasp_store.grasp_types``): a run that makes power grasps only has nothing to split. Held is the lift test;
"held in six directions" also resisted all six pushes; distinct held grasps are those whose palms differ by more than
the run's distinct-grasp rule (section ``diversity``) on the same object, counted within each type.
"""

from __future__ import annotations

import html
from collections.abc import Mapping

import numpy as np
import pandas as pd

from dexlite_pipeline.evaluation.config import DiversityConfig
from dexlite_pipeline.evaluation.diversity import distinct_grasp_labels
from dexlite_pipeline.evaluation.labels import method_label, percent_text, split_label
from dexlite_pipeline.io.grasp_store import GraspSet, grasp_types

COLUMNS = ("method", "split", "grasp_type", "attempts", "held", "held_six_directions", "distinct_held")


def distinct_rule(config: Mapping) -> DiversityConfig:
    """The run's distinct-grasp rule (section ``diversity`` of its config; the defaults where it says nothing)."""
    section = dict(config.get("diversity") or {})
    defaults = DiversityConfig()
    return DiversityConfig(distinct_translation_m=float(section.get("distinct_translation_m", defaults.distinct_translation_m)),
                           distinct_rotation_deg=float(section.get("distinct_rotation_deg", defaults.distinct_rotation_deg)))


def _distinct_held(grasps: GraspSet, rows: np.ndarray, rule: DiversityConfig) -> int:
    """How many distinct grasps the held ``rows`` are (palms apart by the rule, per object)."""
    if not len(rows):
        return 0
    labels = distinct_grasp_labels(grasps.hand_pose[rows], grasps.object_id[rows].astype(str), rule.distinct_translation_m,
                                   rule.distinct_rotation_deg)
    return len({(str(o), int(label)) for o, label in zip(grasps.object_id[rows], labels)})


def type_counts(simulated: GraspSet | None, rule: DiversityConfig) -> pd.DataFrame | None:
    """One row per (method, split, grasp type) with ``COLUMNS``; None when the grasps hold fewer than two types."""
    if simulated is None or not len(simulated) or "lift_success" not in simulated.arrays:
        return None
    types = grasp_types(simulated)
    if len(set(types.tolist())) < 2:
        return None
    method = np.asarray([str(m) for m in simulated.arrays.get("method", np.full(len(simulated), "", dtype=object))])
    split = np.asarray([str(s) for s in simulated.arrays.get("split", np.full(len(simulated), "", dtype=object))])
    held = np.asarray(simulated.arrays["lift_success"], bool)
    six = np.asarray(simulated.arrays.get("six_dir_success", np.zeros(len(simulated), bool)), bool) & held
    rows = []
    for key in dict.fromkeys(zip(method.tolist(), split.tolist(), types.tolist())):
        mine = (method == key[0]) & (split == key[1]) & (types == key[2])
        rows.append({"method": key[0], "split": key[1], "grasp_type": key[2], "attempts": int(mine.sum()), "held": int((mine & held).sum()),
                     "held_six_directions": int((mine & six).sum()), "distinct_held": _distinct_held(simulated, np.flatnonzero(mine & held), rule)})
    return pd.DataFrame(rows, columns=list(COLUMNS)).sort_values(["method", "split", "grasp_type"], kind="stable").reset_index(drop=True)


def grasp_types_html(simulated: GraspSet | None, config: Mapping) -> str:
    """The section's HTML ('' when the grasps hold fewer than two types)."""
    table = type_counts(simulated, distinct_rule(config))
    if table is None:
        return ""
    body = "".join(
        f"<tr><td>{html.escape(method_label(r.method))}</td><td>{html.escape(split_label(r.split) if r.split else '')}</td>"
        f"<td>{html.escape(r.grasp_type)}</td><td>{r.attempts}</td><td>{r.held} ({percent_text(r.held / r.attempts if r.attempts else float('nan'))})</td>"
        f"<td>{r.held_six_directions}</td><td>{r.distinct_held}</td></tr>"
        for r in table.itertuples(index=False)
    )  # fmt: skip
    return (
        "<h2>Grasp types</h2><p class='note'>Per method and grasp type (power, pinch, tripod, lateral, rim: the type each grasp was made "
        "or sampled as): grasps tried, held in the lift test (share of those tried), held against all six pushes too, and distinct "
        "held grasps (palms apart by the run's distinct-grasp rule, per object, within the type).</p>"
        "<table class='text'><thead><tr><th>method</th><th>split</th><th>grasp type</th><th>tried</th><th>held</th>"
        f"<th>held in six directions</th><th>distinct held</th></tr></thead><tbody>{body}</tbody></table>"
    )
