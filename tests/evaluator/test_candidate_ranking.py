"""Ranking a round's candidates by the learned evaluator: per object the best-scored distinct grasps, as many as asked,
each with its score and its place in the ranking."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from test_evaluator_training import objects_dir  # noqa: F401  (the module's fixture: four prepared objects and a catalog)

from dexlite_pipeline.evaluation.config import DiversityConfig
from dexlite_pipeline.evaluator.ranking import rank_candidates
from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.model.evaluator import EvaluatorConfig, GraspEvaluator, load_evaluator, save_evaluator, score_grasps


@pytest.fixture(scope="module")
def evaluator_file(tmp_path_factory):
    """An untrained but deterministic evaluator (the ranking's plumbing does not depend on what it learned)."""
    config = EvaluatorConfig(points_per_cloud=128, pointnet_points=64, pointnet_widths=(8, 16), hand_points_per_shape=2, hidden_sizes=(16,))
    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("evaluator") / "evaluator.pt"
    save_evaluator(path, GraspEvaluator(config), config, {"train_object_ids": ["box"]})
    return path


def test_rank_candidates_keeps_the_best_distinct_grasps_per_object(objects_dir, evaluator_file):  # noqa: F811
    rng = np.random.default_rng(0)
    ids = np.repeat(np.array(["box", "sphere"], dtype=object), 20)
    pose = np.zeros((40, 28), np.float32)
    pose[:, :3] = rng.normal(0.0, 0.1, (40, 3))
    pose[:, 3:6] = rng.uniform(-np.pi, np.pi, (40, 3))
    model, _ = load_evaluator(evaluator_file)
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.objects.assets import load_asset

    clouds = ObjectClouds([load_asset([str(objects_dir)], o) for o in ("box", "sphere")])
    best = int(np.argmax(score_grasps(model, pose[:20], clouds, ids[:20], np.full(20, 0.08, np.float32))))
    duplicate = (best + 1) % 20
    pose[duplicate] = pose[best] + np.float32(0.001)  # a near-duplicate of the box's best grasp: it scores as high
    candidates = GraspSet({"hand_pose": pose, "object_id": ids, "scale": np.full(40, 0.08, np.float32), "method": np.full(40, "cvae_loop", dtype=object)})
    kept, attrs = rank_candidates(candidates, str(evaluator_file), [str(objects_dir)], None, keep=6, diversity=DiversityConfig(), table=False,
                                  device="cpu")
    assert attrs["pool"] == 40 and attrs["kept"] == 12 and len(kept) == 12
    scores = score_grasps(model, pose, clouds, ids, np.full(40, 0.08, np.float32))
    for object_id in ("box", "sphere"):
        mine = kept.object_id.astype(str) == object_id
        assert sorted(kept.arrays["evaluator_rank"][mine].tolist()) == list(range(6))
        by_rank = np.argsort(kept.arrays["evaluator_rank"][mine])
        ranked_scores = kept.arrays["evaluator_score"][mine][by_rank]
        assert (np.diff(ranked_scores) <= 1e-6).all()  # distinct ones first, best first (all distinct here but 4 and 5)
        rows = np.flatnonzero(ids == object_id)
        assert np.isclose(ranked_scores[0], scores[rows].max(), atol=1e-5)
    kept_rows = {i for i in range(40) if any((pose[i] == p).all() for p in kept.hand_pose)}
    assert len(kept_rows) == 12 and len({best, duplicate} & kept_rows) == 1  # the best grasp, once (not its near-duplicate too)
