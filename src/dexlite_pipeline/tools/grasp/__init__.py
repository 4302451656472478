"""Grasps that hold for the user's own meshes, in one call: ``dexlite grasp MESH [MESH ...] --out DIR``.

Steps (each logs its progress):

0. check everything before any work: options, config, device, model file, every mesh file
   (readable, a size plausible for a hand-held object in the given ``units``) and the output
   folder; any problem is one ``GraspToolError`` and nothing is written;
1. prepare every mesh that fits the Shadow Hand (repair, normalization, convex pieces, SDF)
   into ``DIR/objects``; one too large or too small for the hand, or that cannot be prepared,
   is listed with its reason and the others go on;
2. synthesize ``n`` grasps per object, **at the object's real size** (the mesh's own size in
   ``units``), or with ``resize_to_training`` at the training scales (object radius 8-12 cm):
   with a trained model (``cvae.pt``), CVAE samples refined by post-optimization (config
   sections ``sample`` and ``post_optimize``); without one, energy optimization from scratch
   (section ``optimize_grasps``, the pipeline's optimization from scratch);
3. lift test and six-direction test of every grasp with the ``lift`` section's constants
   (the pipeline's physics, unchanged);
4. with a model and ``min_distinct`` > 0, the top-up: each object whose grasps so far give
   fewer than ``min_distinct`` distinct held grasps gets a batch of ``n`` grasps by optimization
   from scratch (the same function and lift test as without a model; the first batch has the
   seeds of ``--from-scratch``), batch after batch until it has ``min_distinct`` or
   ``top_up_batches`` batches were tried; every grasp records its ``source`` (``model`` or
   ``optimization``);
5. distinct grasps among those held (``evaluation.diversity``, section ``diversity``) over
   both sources together, the better grasps first; with ``distinct`` only one of each
   near-duplicate is kept;
6. write ``DIR/grasps.zarr`` (the kept held grasps, same schema as the pipeline's stores),
   ``DIR/all_grasps.zarr`` (every grasp with its failure reason and distinct-grasp label),
   ``DIR/dexgraspnet/`` (DexGraspNet layout of the kept grasps and meshes, when any held),
   ``DIR/renders/*.png`` (different grasps), ``DIR/view.html`` (the kept grasps in an offline,
   turnable 3-D view) and ``DIR/summary.md``.

Settings are the package's default ``config.yaml`` overlaid by the caller's sections, read as
the typed tree (``settings.build_config``); the physics constants of the lift test are never
changed here. Sizes: the store's ``scale`` is the unit (metres) per file unit divided by the
asset's ``normalization_factor``, so the README's object-frame rule (p / scale /
normalization_factor + normalization_centre) gives back the mesh file's coordinates.

The modules, one job each: ``request`` (what a run is asked and gives back, the defaults), ``checks`` (step 0),
``synthesis`` (steps 2 and 4: the model, optimization from scratch, the top-up), ``selection`` (distinct grasps,
step 5), ``outputs`` (the stores, export, pictures and 3-D view of step 6), ``summary`` (``summary.md`` and what to
try next) and ``run`` (``run_grasp_tool``: the steps in order, timed into a ``RunRecord``).
"""

from dexlite_pipeline.tools.grasp.checks import MeshSize, check_request
from dexlite_pipeline.tools.grasp.request import (
    DEFAULT_GRASPS_PER_OBJECT, DEFAULT_MIN_DISTINCT, DEFAULT_RENDERS_PER_OBJECT, DEFAULT_TOP_UP_BATCHES, UNIT_METRES, GraspOutcome,
    GraspRequest, GraspToolError,
)  # fmt: skip
from dexlite_pipeline.tools.grasp.run import run_grasp_tool
from dexlite_pipeline.tools.grasp.selection import distinct_labels, grasp_rank, representatives
from dexlite_pipeline.tools.grasp.summary import summary_markdown
from dexlite_pipeline.tools.grasp.synthesis import (
    concatenate_sources, objects_to_top_up, synthesize_from_scratch, synthesize_with_model, top_up_seed, top_up_until_distinct,
)  # fmt: skip

__all__ = [
    "DEFAULT_GRASPS_PER_OBJECT", "DEFAULT_MIN_DISTINCT", "DEFAULT_RENDERS_PER_OBJECT", "DEFAULT_TOP_UP_BATCHES", "UNIT_METRES",
    "GraspOutcome", "GraspRequest", "GraspToolError", "MeshSize", "check_request", "concatenate_sources", "distinct_labels",
    "grasp_rank", "objects_to_top_up", "representatives", "run_grasp_tool", "summary_markdown", "synthesize_from_scratch",
    "synthesize_with_model", "top_up_seed", "top_up_until_distinct",
]  # fmt: skip
