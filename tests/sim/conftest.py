"""Fixtures of the simulation tests: prepared bars and the hook grasp that encloses each."""

from __future__ import annotations

import pytest
from bar_grasps import BAR_IDS, hook_grasp, write_bars

from dexlite_pipeline.objects.assets import load_asset


@pytest.fixture(scope="session")
def objects_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("sim_objects")
    write_bars(root)
    return root


@pytest.fixture(scope="session")
def hooks(hand, objects_dir):
    """Object id -> the constructed enclosing grasp (28-vector) of that bar."""
    return {oid: hook_grasp(hand, load_asset(objects_dir, oid)) for oid in BAR_IDS}
