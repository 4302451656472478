"""Where the tests find the optional DexGraspNet sample (real grasps of two objects, kept out of
the repository): the folder named by $DEXLITE_DEXGRASPNET_SAMPLE, else the team's copy in
``shared/dexgraspnet_sample`` beside the checkout. Tests that need it skip where it is absent."""

from __future__ import annotations

import os
from pathlib import Path

SAMPLE_VARIABLE = "DEXLITE_DEXGRASPNET_SAMPLE"
BESIDE_CHECKOUT = Path(__file__).resolve().parents[1].parent / "shared" / "dexgraspnet_sample"


def dexgraspnet_sample_dir() -> Path:
    """The sample's folder (it may not exist: callers check for ``dataset/``)."""
    named = os.environ.get(SAMPLE_VARIABLE)
    return Path(named).expanduser() if named else BESIDE_CHECKOUT
