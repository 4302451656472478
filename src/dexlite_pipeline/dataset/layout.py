"""The grasp dataset's folder layout and schema, in one place.

A dataset is a folder kept in git, grown batch by batch::

    DATASET/CARD.md                  generated data card (card.write_card; never edited by hand)
    DATASET/objects.csv              one row per object (OBJECT_COLUMNS)
    DATASET/batches.csv              one row per batch (BATCH_COLUMNS); the commit point of an addition
    DATASET/configs/batch_NNNN.json  the full config of batch NNNN
    DATASET/grasps/batch_NNNN.npz    every grasp of batch NNNN, held or not (GRASP_ARRAYS)

Adding a batch writes two new files and rewrites the two small tables, so a git diff of an
addition is the new files plus a few table rows. Every file is written deterministically (same
inputs, same bytes) and atomically.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import re
import subprocess
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from dexlite_pipeline.config import json_ready
from dexlite_pipeline.evaluation.config import DiversityConfig
from dexlite_pipeline.hand.model import POSE_DIM
from dexlite_pipeline.io.grasp_store import DEFAULT_GRASP_TYPE, GRASP_TYPE
from dexlite_pipeline.objects.rest_pose import REST_QUATERNION_COLUMNS, SUPPORT_NORMAL_COLUMNS, SUPPORT_OFFSET_COLUMN

SCHEMA_VERSION = 1
CARD_NAME = "CARD.md"
OBJECTS_TABLE = "objects.csv"
BATCHES_TABLE = "batches.csv"
CONFIGS_DIR = "configs"
GRASPS_DIR = "grasps"
BATCH_DIGITS = 4  # batch_0001 ... batch_9999

# The distinct-grasp rule of the whole dataset (evaluation.diversity): palms within these are one grasp.
DISTINCT_TRANSLATION_M = DiversityConfig.distinct_translation_m  # 0.02 m
DISTINCT_ROTATION_DEG = DiversityConfig.distinct_rotation_deg  # 30 deg
NOT_HELD_LABEL = -1  # distinct_label of a grasp that was not held

# The campaign's target: this many household training objects with this many distinct held grasps each.
TARGET_OBJECTS = 200
TARGET_DISTINCT_PER_OBJECT = 30


@dataclass(frozen=True)
class ArraySpec:
    """One per-grasp array: its kind ("str", "float32", "bool", "int32"), shape after the first (N) axis, meaning;
    ``absent``: what an optional array reads as in the rows of a batch without it (``load_dataset``)."""

    kind: str
    trailing_shape: tuple[int, ...]
    meaning: str
    absent: object = None


ENERGY_MEANING = "float32 energy term of the grasp (NaN where the term was not computed)"
# Arrays every batch must give (in this order in the card).
REQUIRED_ARRAYS: dict[str, ArraySpec] = {
    "object_id": ArraySpec("str", (), "the object's id (a row of objects.csv)"),
    "scale": ArraySpec("float32", (), "object scale: the prepared mesh times this is the object in metres"),
    "hand_pose": ArraySpec("float32", (POSE_DIM,), "palm position (m), xyz Euler angles (rad), 22 joint angles (rad), object frame"),
    "E_fc": ArraySpec("float32", (), "force-closure energy (NaN where absent)"),
    "E_dis": ArraySpec("float32", (), "contact distance energy, m (NaN where absent)"),
    "E_pen": ArraySpec("float32", (), "hand-object penetration energy, m (NaN where absent)"),
    "E_spen": ArraySpec("float32", (), "hand self-penetration energy, m (NaN where absent)"),
    "E_joints": ArraySpec("float32", (), "joint-limit energy, rad (NaN where absent)"),
    "E_table": ArraySpec("float32", (), "hand-table penetration energy, m (NaN where absent, e.g. floating mode)"),
    "initial_penetration_mm": ArraySpec("float32", (), "the lift test's start depth of the hand in the object, mm"),
    "lift_success": ArraySpec("bool", (), "held: the object stayed in the hand when lifted off its table"),
    "six_dir_success": ArraySpec("bool", (), "the grasp resisted pushes in all six directions"),
    "failure_reason": ArraySpec("str", (), "why the lift test failed ('' when held)"),
    "source": ArraySpec("str", (), "what made the grasp: optimization, loop_round_<r>, model, ..."),
}
# The grasp type array. Batches made before grasp types existed lack it: optimization from scratch then had the power
# template only, so their grasps are power grasps, and they load as such (its ``absent`` value; the card says so).
GRASP_TYPE_ARRAY = GRASP_TYPE  # "grasp_type"
GRASP_TYPE_ABSENT = DEFAULT_GRASP_TYPE  # "power"
# Arrays a batch may give (tabletop mode records the table of each grasp, tabletop.store_arrays; optimization from
# scratch the type of each grasp, optim.grasp_types).
SUPPORT_PLANE_ARRAYS = ("support_normal", "support_offset_m")  # both or neither
OPTIONAL_ARRAYS: dict[str, ArraySpec] = {
    "support_normal": ArraySpec("float32", (3,), "the table's upward unit normal in the object frame", np.nan),
    "support_offset_m": ArraySpec("float32", (), "height of the object origin above the table at the grasp's scale, m", np.nan),
    GRASP_TYPE_ARRAY: ArraySpec("str", (), "the grasp's type: power, pinch, tripod or lateral (optimize_grasps.grasp_types); "
                                "a batch without it was made before grasp types, with the power template: power", GRASP_TYPE_ABSENT),
}
# Arrays the dataset assigns: ignored when given to add_batch, recomputed there.
ASSIGNED_ARRAYS: dict[str, ArraySpec] = {
    "distinct_label": ArraySpec("int32", (), "distinct held grasp of its object, consistent over the dataset (-1: not held)"),
}
STORED_ARRAYS: dict[str, ArraySpec] = {**REQUIRED_ARRAYS, **OPTIONAL_ARRAYS, **ASSIGNED_ARRAYS}
# load_dataset adds this array (not stored: a grasp's batch is the file it is in).
BATCH_ARRAY = "batch"

# objects.csv: the columns an objects frame given to add_batch must / may have, then the columns it computes.
OBJECT_REQUIRED_COLUMNS = ("object_id", "source", "split")
OBJECT_OPTIONAL_TEXT_COLUMNS = ("rebuild",)
OBJECT_OPTIONAL_FLOAT_COLUMNS = ("real_radius_m", *SUPPORT_NORMAL_COLUMNS, SUPPORT_OFFSET_COLUMN, *REST_QUATERNION_COLUMNS)
OBJECT_COMPUTED_COLUMNS = ("scales", "batch")
OBJECT_COLUMNS = (
    "object_id", "source", "rebuild", "real_radius_m", "scales",
    *SUPPORT_NORMAL_COLUMNS, SUPPORT_OFFSET_COLUMN, *REST_QUATERNION_COLUMNS, "split", "batch",
)  # fmt: skip
# Columns that say what an object is: two datasets holding the same id must agree on these.
OBJECT_IDENTITY_COLUMNS = tuple(c for c in OBJECT_COLUMNS if c not in OBJECT_COMPUTED_COLUMNS)
SPLITS = ("train", "heldout")

BATCH_COLUMNS = (
    "batch", "kind", "n_objects", "objects", "grasps", "held", "distinct_held_added",
    "code_version", "config_digest", "machine", "cpu_seconds", "started_utc", "finished_utc", "protocol",
)  # fmt: skip
BATCH_INT_COLUMNS = ("n_objects", "grasps", "held", "distinct_held_added")
BATCH_KIND_PATTERN = re.compile(r"^(optimization|model|loop_round_[1-9][0-9]*)$")
OPTIMIZATION_KIND = "optimization"  # the only kind that must not add grasps to objects already present


def batch_name(batch_id: int) -> str:
    """The zero-padded batch id ("0007") used in file names and tables."""
    return f"{int(batch_id):0{BATCH_DIGITS}d}"


def grasps_path(dataset_dir: str | os.PathLike, batch_id: int) -> Path:
    return Path(dataset_dir) / GRASPS_DIR / f"batch_{batch_name(batch_id)}.npz"


def config_path(dataset_dir: str | os.PathLike, batch_id: int) -> Path:
    return Path(dataset_dir) / CONFIGS_DIR / f"batch_{batch_name(batch_id)}.json"


def machine_description() -> str:
    """This machine as a batch row records it: platform and CPU count (what the CPU seconds ran on)."""
    return f"{platform.platform()}; {os.cpu_count()} CPUs"


def utc_timestamp() -> str:
    """Now in UTC as ISO 8601 to the second ("2026-05-01T09:45:00Z"): a batch's started / finished time."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds").replace("+00:00", "Z")


def code_version(repo_dir: str | os.PathLike | None = None) -> str:
    """The git commit of the code (``repo_dir``: default the checkout holding this package), "+dirty" appended
    when tracked files have uncommitted changes; "unknown" outside a git checkout."""
    where = str(repo_dir or Path(__file__).resolve().parent)
    try:
        commit = subprocess.run(["git", "-C", where, "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
        changes = subprocess.run(["git", "-C", where, "status", "--porcelain", "--untracked-files=no"],
                                 capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return f"{commit}+dirty" if changes else commit


def canonical_json(value) -> str:
    """``value`` as JSON with sorted keys and fixed separators: equal configs give equal text."""
    return json.dumps(json_ready(value), sort_keys=True, separators=(",", ":"), allow_nan=True)


def config_digest(config: dict) -> str:
    """First 16 hex digits of the SHA-256 of the config's canonical JSON."""
    return hashlib.sha256(canonical_json(config).encode()).hexdigest()[:16]


def default_rebuild(object_id: str, source: str) -> str:
    """What rebuilds an object's mesh, from its id, when the frame does not say.

    ``household:<id>`` for generated household objects (``objects.household.household_object``),
    ``pybullet_data:<file>`` for the embedded pybullet_data objects (file relative to
    ``pybullet_data.getDataPath()``), '' when unknown (a user's mesh).
    """
    from dexlite_pipeline.objects.household import parse_household_id
    from dexlite_pipeline.objects.sources import NAMED_PYBULLET_OBJECTS, RANDOM_URDF_DIR

    if source.startswith("household"):
        try:
            parse_household_id(object_id)
            return f"household:{object_id}"
        except ValueError:
            return ""
    if object_id.startswith("pb-random-"):
        number = object_id.removeprefix("pb-random-")
        return f"pybullet_data:{RANDOM_URDF_DIR}/{number}/{number}.urdf"
    if object_id.startswith("pb-") and object_id.removeprefix("pb-") in NAMED_PYBULLET_OBJECTS:
        return f"pybullet_data:{NAMED_PYBULLET_OBJECTS[object_id.removeprefix('pb-')]}"
    return ""


def object_family(object_id: str, source: str) -> str:
    """The family an object is counted in: its household family (``objects.family``), else its source."""
    from dexlite_pipeline.objects.family import HOUSEHOLD_PREFIX
    from dexlite_pipeline.objects.family import object_family as family_of_id

    family = family_of_id(object_id) if object_id.startswith(HOUSEHOLD_PREFIX) else "other"
    return family if family != "other" else (source or "unknown")


def is_household_training(object_id: str, split: str) -> bool:
    """Whether an object counts toward the campaign's target: a generated household object in the training split."""
    from dexlite_pipeline.objects.household import parse_household_id

    if split != "train":
        return False
    try:
        parse_household_id(object_id)
    except ValueError:
        return False
    return True


@dataclass
class BatchRecord:
    """What a batch says about itself: the caller's part of its batches.csv row, and its config.

    The store fills in the rest of the row (batch id, object and grasp counts, config digest).
    ``cpu_seconds``: CPU time per stage in seconds, e.g. {"optimize": 5400.0, "lift_test": 900.0}.
    ``started_utc`` / ``finished_utc``: ISO 8601 timestamps in UTC (e.g. "2026-05-01T10:00:00Z").
    ``code_version``: the git commit the batch ran. ``protocol``: one short sentence of how it was made.
    """

    kind: str  # optimization, loop_round_<r> or model
    code_version: str
    config: dict
    cpu_seconds: dict[str, float]
    started_utc: str
    finished_utc: str
    protocol: str = ""
    machine: str = field(default_factory=machine_description)
