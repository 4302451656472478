"""A dataset's grasps as a run's training data: which objects the run takes from it, and when an object's grasps
do not fit the run's prepared object (scale or table differ), so they are left out with the reason."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
from test_store import MUGS, make_grasps, objects_frame, record

from dexlite_pipeline.dataset import add_batch
from dexlite_pipeline.dataset.for_run import _mismatch, dataset_training_objects
from dexlite_pipeline.objects.assets import CATALOG_NAME
from dexlite_pipeline.objects.rest_pose import SupportPlane
from dexlite_pipeline.tabletop import SupportPlanes


def test_the_run_takes_its_training_objects_that_the_dataset_holds(tmp_path):
    dataset = tmp_path / "dataset"
    add_batch(dataset, make_grasps(MUGS + ["household-cup-000"]), objects_frame(MUGS + ["household-cup-000"]), record())
    objects = tmp_path / "objects"
    objects.mkdir()
    pd.DataFrame({"object_id": [MUGS[0], MUGS[1], "household-cup-000", "household-can-000"], "split": ["train", "heldout", "train", "train"],
                  "status": ["ok", "ok", "rejected", "ok"]}).to_parquet(objects / CATALOG_NAME)
    # a held-out object is never taken (nor one the run rejected, nor one the dataset lacks)
    assert dataset_training_objects(dataset, [str(objects)]) == {MUGS[0]}


def test_grasps_that_do_not_fit_the_prepared_object_are_left_out():
    grasps = make_grasps(MUGS[:1], per_object=4, scale=0.1)  # table normal +z, 5 cm under the origin
    asset = SimpleNamespace(real_scale=0.1)
    planes = SupportPlanes({MUGS[0]: SupportPlane((0.0, 0.0, 1.0), 0.5)})  # 0.5 per unit scale = 5 cm at 0.1
    assert _mismatch(MUGS[0], grasps, asset, planes) == ""
    assert _mismatch(MUGS[0], grasps, asset, None) == ""  # floating run: only the scale matters
    assert "real scale" in _mismatch(MUGS[0], grasps, SimpleNamespace(real_scale=0.12), planes)
    tilted = SupportPlanes({MUGS[0]: SupportPlane((0.0, np.sin(0.1), np.cos(0.1)), 0.5)})
    assert "resting pose differs" in _mismatch(MUGS[0], grasps, asset, tilted)
    higher = SupportPlanes({MUGS[0]: SupportPlane((0.0, 0.0, 1.0), 0.52)})  # 2 mm apart
    assert "resting pose differs" in _mismatch(MUGS[0], grasps, asset, higher)
    assert "no resting pose" in _mismatch(MUGS[0], grasps, asset, SupportPlanes({}))
    floating = make_grasps(MUGS[:1], per_object=4, scale=0.1, tabletop=False)
    assert "records no table" in _mismatch(MUGS[0], floating, asset, planes)
