"""The optional real DexGraspNet sample (real grasps of two objects, kept out of the repository).

Tests that read it are marked ``real_sample`` and run only when $DEXLITE_DEXGRASPNET_SAMPLE
names a DexGraspNet download (``dataset/``, ``meshdata/``); otherwise they are deselected, so
a bare clone runs every other test and reports none of these as skipped (tests/conftest.py).
"""

from __future__ import annotations

import os
from pathlib import Path

from fixtures.make_grasp_fixture import FIXTURE_DIR, FIXTURE_OBJECTS

SAMPLE_VARIABLE = "DEXLITE_DEXGRASPNET_SAMPLE"
MARKER = "real_sample"


def dexgraspnet_sample_dir() -> Path | None:
    """The folder $DEXLITE_DEXGRASPNET_SAMPLE names, or None when it is not set."""
    named = os.environ.get(SAMPLE_VARIABLE)
    return Path(named).expanduser() if named else None


# The committed grasp fixture: grasps the pipeline found and lift-tested itself, in DexGraspNet's
# layout (made by fixtures/make_grasp_fixture.py; the first object trains, the second is held out).
GRASP_FIXTURE = FIXTURE_DIR
FIXTURE_TRAIN_OBJECT, FIXTURE_HELDOUT_OBJECT = FIXTURE_OBJECTS

# DexGraspNet's grasp files as its authors write them: a 1-D object array of dicts with keys
# 'qpos' and 'scale' (a numpy float64); qpos maps the 22 finger joints (radians), then the palm's
# static-axis x-y-z Euler angles and its translation (metres), in this order, to Python floats.
DEXGRASPNET_JOINT_KEYS = tuple(
    f"robot0:{finger}J{i}" for finger, count in (("FF", 4), ("MF", 4), ("RF", 4), ("LF", 5), ("TH", 5)) for i in reversed(range(count))
)
DEXGRASPNET_QPOS_ORDER = (*DEXGRASPNET_JOINT_KEYS, "WRJRx", "WRJRy", "WRJRz", "WRJTx", "WRJTy", "WRJTz")
