"""The report counts grasp types (report.grasp_types) where the grasps hold several, and the views name each grasp's type."""

from __future__ import annotations

import numpy as np

from dexlite_pipeline.evaluation.config import DiversityConfig
from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.report.grasp_types import grasp_types_html, type_counts
from dexlite_pipeline.report.grasp_view import grasp_label


def palm_at(x_m: float) -> np.ndarray:
    pose = np.zeros(28, np.float32)
    pose[0] = x_m
    return pose


def simulated(types) -> GraspSet:
    """Six grasps of one object by one method: held, held, held (the first two one distinct grasp), dropped, held, dropped."""
    poses = np.stack([palm_at(x) for x in (0.0, 0.005, 0.1, 0.2, 0.3, 0.4)])
    return GraspSet({
        "hand_pose": poses, "object_id": np.full(6, "mug", dtype=object), "scale": np.full(6, 0.1, np.float32),
        "method": np.full(6, "cvae_post", dtype=object), "split": np.full(6, "heldout", dtype=object),
        "lift_success": np.array([True, True, True, False, True, False]), "six_dir_success": np.array([True, False, True, False, False, False]),
        "grasp_type": np.asarray(types, dtype=object),
    })  # fmt: skip


def test_held_and_distinct_held_grasps_are_counted_per_type():
    table = type_counts(simulated(["pinch", "pinch", "power", "power", "pinch", "pinch"]), DiversityConfig())
    pinch = table[table["grasp_type"] == "pinch"].iloc[0]
    power = table[table["grasp_type"] == "power"].iloc[0]
    assert (pinch["attempts"], pinch["held"], pinch["held_six_directions"], pinch["distinct_held"]) == (4, 3, 1, 2)  # rows 0, 1 one grasp
    assert (power["attempts"], power["held"], power["held_six_directions"], power["distinct_held"]) == (2, 1, 1, 1)
    text = grasp_types_html(simulated(["pinch", "pinch", "power", "power", "pinch", "pinch"]), {})
    assert "<h2>Grasp types</h2>" in text and "<td>pinch</td><td>4</td><td>3 (75.0%)</td><td>1</td><td>2</td>" in text


def test_one_type_shows_no_table_and_a_store_without_types_is_power():
    assert type_counts(simulated(["power"] * 6), DiversityConfig()) is None
    untyped = simulated(["power"] * 6)
    del untyped.arrays["grasp_type"]
    assert grasp_types_html(untyped, {}) == ""


def test_the_3d_views_label_names_the_type():
    grasps = simulated(["tripod", "power", "power", "power", "power", "power"])
    assert grasp_label(grasps.arrays, 0).startswith("cvae_post · tripod grasp · mug")
    del grasps.arrays["grasp_type"]
    assert "power grasp" in grasp_label(grasps.arrays, 0)
