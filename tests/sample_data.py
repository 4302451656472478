"""The optional real DexGraspNet sample (real grasps of two objects, kept out of the repository).

Tests that read it are marked ``real_sample`` and run only when $DEXLITE_DEXGRASPNET_SAMPLE
names a DexGraspNet download (``dataset/``, ``meshdata/``); otherwise they are deselected, so
a bare clone runs every other test and reports none of these as skipped (tests/conftest.py).
"""

from __future__ import annotations

import os
from pathlib import Path

SAMPLE_VARIABLE = "DEXLITE_DEXGRASPNET_SAMPLE"
MARKER = "real_sample"


def dexgraspnet_sample_dir() -> Path | None:
    """The folder $DEXLITE_DEXGRASPNET_SAMPLE names, or None when it is not set."""
    named = os.environ.get(SAMPLE_VARIABLE)
    return Path(named).expanduser() if named else None
