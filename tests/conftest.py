"""Shared fixtures: the hand model (built once per session) and the optional real DexGraspNet sample.

Tests marked ``real_sample`` read the real sample and are deselected unless
$DEXLITE_DEXGRASPNET_SAMPLE is set (``sample_data``); every other test needs nothing outside
the repository.
"""

from pathlib import Path

import pytest
from sample_data import MARKER, SAMPLE_VARIABLE, dexgraspnet_sample_dir


def pytest_report_header(config):
    sample = dexgraspnet_sample_dir()
    if sample is None:
        return f"{MARKER} tests: deselected (set {SAMPLE_VARIABLE} to a DexGraspNet download to run them)"
    return f"{MARKER} tests: on {sample}"


def pytest_collection_modifyitems(config, items):
    """Deselect the tests on the real sample when no sample is named (they are an optional extra)."""
    unmarked = [item.nodeid for item in items if "dexgraspnet_sample" in getattr(item, "fixturenames", ()) and not item.get_closest_marker(MARKER)]
    if unmarked:
        raise pytest.UsageError(f"tests that read the real DexGraspNet sample must be marked {MARKER}: {', '.join(unmarked)}")
    if dexgraspnet_sample_dir() is not None:
        return
    deselected = [item for item in items if item.get_closest_marker(MARKER)]
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = [item for item in items if not item.get_closest_marker(MARKER)]


@pytest.fixture(scope="session")
def hand():
    from dexlite_pipeline.hand import ShadowHand

    return ShadowHand()


@pytest.fixture(scope="session")
def dexgraspnet_sample() -> Path:
    """The real DexGraspNet sample named by $DEXLITE_DEXGRASPNET_SAMPLE (tests marked real_sample only)."""
    sample = dexgraspnet_sample_dir()
    if sample is None or not (sample / "dataset").is_dir():
        pytest.fail(f"{SAMPLE_VARIABLE}={sample}: not a DexGraspNet download (no dataset/ folder)")
    return sample
