"""The lift test on real DexGraspNet grasps (a DexGraspNet download named by $DEXLITE_DEXGRASPNET_SAMPLE; deselected without it).

These grasps were made and validated by another system. A prototype of this protocol
passed 79% of such grasps at friction 0.6 (88% at 1.0) and 0% once moved away; the full
494-grasp sample passes 72.3% here at friction 0.6 under the 2 mm start cap (76.5% under a 1 cm cap). A seeded subset keeps
the test short; the subset is fixed, so its pass count is not a sample statistic but a
deterministic result, and the test pins it (see ``EXPECTED_PASSES``).
"""

from __future__ import annotations

import numpy as np
import pytest

from dexlite_pipeline.sim.config import LiftConfig
from dexlite_pipeline.sim.lift import run_lift_tests

pytestmark = pytest.mark.real_sample

SUBSET = 64
# The subset passes 46 of 64 (4 start deeper than the 2 mm cap; 48 under a 1 cm cap), the same on every run. The tolerance is for another platform's
# floating point (other CPU, compiler, BLAS): measured, noise of 1e-4 and 3e-4 (metres,
# radians) added to every pose flipped none of the 64 outcomes in four runs, and 1e-3 flipped
# one in two runs, while rounding differences are ~1e-7. Two grasps either way leave room for
# a marginal grasp or two and fail any change of the simulation worth 3 grasps (5 points).
EXPECTED_PASSES = 46
PASS_TOLERANCE = 2


@pytest.fixture(scope="module")
def sample(dexgraspnet_sample, tmp_path_factory):
    """The sample imported by the project's importer (restricted unpickler) at a coarse grid, and a seeded subset."""
    from dexlite_pipeline.io.config import DexGraspNetConfig
    from dexlite_pipeline.io.dexgraspnet import import_dexgraspnet
    from dexlite_pipeline.objects.config import AssetBuildSettings

    objects = tmp_path_factory.mktemp("dexgraspnet_objects")
    settings = AssetBuildSettings(sdf_resolution=48, surface_points=2048)
    result = import_dexgraspnet(dexgraspnet_sample, objects, settings, DexGraspNetConfig(), seed=0)
    assert len(result.grasps) == 494
    subset = np.sort(np.random.default_rng(0).choice(len(result.grasps), SUBSET, replace=False))
    return result.grasps.select(subset), objects


@pytest.mark.slow
def test_real_grasps_pass_at_the_prototype_rate(sample):
    grasps, objects = sample
    result = run_lift_tests(grasps, [objects], LiftConfig(), threads=1)
    passes = int(result["lift_success"].sum())
    assert abs(passes - EXPECTED_PASSES) <= PASS_TOLERANCE, f"{passes} of {len(grasps)} real grasps pass at friction 0.6, expected {EXPECTED_PASSES}"
    assert set(result["failure_reason"]) <= {"", "dropped", "initial_penetration"}  # a few real grasps start 2-5 mm deep
    assert np.nanmedian(result["initial_penetration_mm"]) < 1.5  # frames right: ~0.6 mm
    ratio = result["lift_ratio"]
    assert np.mean((ratio > 0.5) & (ratio < 0.9)) < 0.05  # bimodal: the object is held or lost


@pytest.mark.slow
def test_real_grasps_moved_away_all_fail(sample):
    grasps, objects = sample
    away = grasps.select(np.arange(16))
    away.arrays["hand_pose"] = away.hand_pose.copy()
    away.arrays["hand_pose"][:, :3] *= 1.0 + 0.5 / np.linalg.norm(away.hand_pose[:, :3], axis=1, keepdims=True)  # 0.5 m further out
    result = run_lift_tests(away, [objects], LiftConfig(), threads=1)
    assert not result["lift_success"].any()
    assert set(result["failure_reason"]) == {"dropped"}
