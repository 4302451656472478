"""Shared fixtures: the hand model (built once per session) and the optional DexGraspNet sample."""

import os
from pathlib import Path

import pytest

# A DexGraspNet download (dataset/, meshdata/) to test against real grasps; those tests skip without it.
SAMPLE_VARIABLE = "DEXLITE_DEXGRASPNET_SAMPLE"


@pytest.fixture(scope="session")
def hand():
    from dexlite_pipeline.hand import ShadowHand

    return ShadowHand()


@pytest.fixture(scope="session")
def dexgraspnet_sample() -> Path:
    """The DexGraspNet download named by $DEXLITE_DEXGRASPNET_SAMPLE, or skip where it is not set or absent."""
    sample = Path(os.environ.get(SAMPLE_VARIABLE, "")).expanduser()
    if not os.environ.get(SAMPLE_VARIABLE) or not (sample / "dataset").is_dir():
        pytest.skip(f"no DexGraspNet sample: set {SAMPLE_VARIABLE} to a download with dataset/ and meshdata/")
    return sample
