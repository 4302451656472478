"""What a ``dexlite grasp`` run is asked (``GraspRequest``), what it gives back (``GraspOutcome``), its defaults and
its one error type (``GraspToolError``: input the tool cannot work with)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

DEFAULT_GRASPS_PER_OBJECT = 32
DEFAULT_RENDERS_PER_OBJECT = 2
UNIT_METRES = {"mm": 0.001, "cm": 0.01, "m": 1.0}
UNIT_NAMES = {"mm": "millimetres", "cm": "centimetres", "m": "metres"}
# The summary suggests what to try for an object with fewer distinct held grasps than this.
WANTED_DISTINCT = 4
# Default --min-distinct: with a model, an object with fewer distinct held model grasps than this also gets grasps
# by optimization from scratch. The same number as the summary's hints, so the tool does by itself what the summary
# would otherwise tell the user to try; a handful of different grasps (palms 2 cm or 30 degrees apart) lets a robot
# pick one whose approach is free of the table, neighbouring objects and its arm's reach limits.
DEFAULT_MIN_DISTINCT = WANTED_DISTINCT
# Default cap of the top-up: at most this many batches of n optimization attempts per object. Optimization holds 5-45%
# of its attempts on household meshes and nearly every held grasp is distinct, so 4 batches of 32 reach 4 distinct
# grasps on all but the hardest shapes, and an object the hand cannot hold costs at most 4 optimizations.
DEFAULT_TOP_UP_BATCHES = 4
# The ``source`` array of the stores: which synthesis made each grasp.
SOURCE_MODEL = "model"
SOURCE_OPTIMIZATION = "optimization"


class GraspToolError(ValueError):
    """Input the tool cannot work with (bad option, device, model file, mesh file or output folder)."""


@dataclass
class GraspRequest:
    """What to grasp and how: mesh files or folders, output folder, budget and options."""

    meshes: list[str]
    out_dir: str
    grasps_per_object: int = DEFAULT_GRASPS_PER_OBJECT
    units: str = "m"  # the mesh files' length unit: mm, cm or m
    resize_to_training: bool = False  # grasp each object resized to the training scales instead of its real size
    distinct: bool = True  # keep one grasp of each near-duplicate group in grasps.zarr
    overwrite: bool = False  # clear an earlier run's output folder first
    device: str | None = None  # None: the config's device
    model: str | None = None  # trained cvae.pt: sample + post-optimize; None: optimization from scratch
    # with a model: a learned grasp evaluator (evaluator.pt) that ranks evaluator.pool_factor x n samples per object and
    # keeps the n best-scored distinct ones before post-optimization; None: the model's first n samples
    evaluator: str | None = None
    # with a model: objects with fewer distinct held model grasps also get optimization from scratch (0: never)
    min_distinct: int = DEFAULT_MIN_DISTINCT
    top_up_batches: int = DEFAULT_TOP_UP_BATCHES  # at most this many top-up batches of n attempts per object
    config: dict = field(default_factory=dict)  # config sections over the defaults
    threads: int = 1
    renders_per_object: int = DEFAULT_RENDERS_PER_OBJECT
    upright_axis: str | None = None  # tabletop mode: the mesh axis pointing up (None: the mesh's stable pose)
    grasp_type: str = "any"  # the grasps' type: any (the model's training mix; optimization's configured shares) or one type
    # from scratch: each object's starts in this many rounds, the later ones dealt to the types that held on it (type_rounds.py)
    type_rounds: int = 1


@dataclass
class GraspOutcome:
    """Counts per object and where the outputs are."""

    objects: list[dict]
    rejected: list[dict]
    held: int
    distinct: int
    total: int
    seconds: float
    summary_path: Path
    next_steps: list[str] = field(default_factory=list)  # what to try next (the summary's list)
    topped_up: list[str] = field(default_factory=list)  # objects that optimization from scratch topped up
