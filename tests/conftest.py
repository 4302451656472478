"""Shared fixtures: the hand model (built once per session) and the optional DexGraspNet sample."""

from pathlib import Path

import pytest
from sample_data import SAMPLE_VARIABLE, dexgraspnet_sample_dir


@pytest.fixture(scope="session")
def hand():
    from dexlite_pipeline.hand import ShadowHand

    return ShadowHand()


@pytest.fixture(scope="session")
def dexgraspnet_sample() -> Path:
    """The DexGraspNet sample (``sample_data``), or skip where it is absent."""
    sample = dexgraspnet_sample_dir()
    if not (sample / "dataset").is_dir():
        pytest.skip(f"no DexGraspNet sample at {sample}: set {SAMPLE_VARIABLE} to a download with dataset/ and meshdata/")
    return sample
