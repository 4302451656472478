"""Shared fixtures: the hand model (built once per session) and the optional DexGraspNet sample."""

from pathlib import Path

import pytest

SHARED_SAMPLE = Path(__file__).resolve().parents[1].parent / "shared" / "dexgraspnet_sample"


@pytest.fixture(scope="session")
def hand():
    from dexlite_pipeline.hand import ShadowHand

    return ShadowHand()


@pytest.fixture(scope="session")
def dexgraspnet_sample() -> Path:
    """The two real DexGraspNet objects in ../shared, or skip where they are absent."""
    if not (SHARED_SAMPLE / "dataset").is_dir():
        pytest.skip(f"DexGraspNet sample not present at {SHARED_SAMPLE}")
    return SHARED_SAMPLE
