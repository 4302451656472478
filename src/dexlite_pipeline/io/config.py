"""The DexGraspNet import's config type: section ``dexgraspnet``.

A leaf of the config tree (``settings``): it imports no import code, so a stage's code hash
(``codehash``) covers this shape without the computation (``io.dexgraspnet``).
"""

from __future__ import annotations

from dataclasses import dataclass

from dexlite_pipeline.config import setting


@dataclass(frozen=True)
class DexGraspNetConfig:
    """Config section ``dexgraspnet``: where the download is and how its objects are split."""

    root: str = setting("", "a DexGraspNet download (dataset/, meshdata/); empty = not used", required=True)
    heldout_fraction: float = setting(
        0.0, "share of imported objects held out for evaluation (seeded per object code)", minimum=0, maximum=1)
    heldout_object_codes: tuple[str, ...] = setting(
        (), "object codes always held out (the rest are training objects)", unique_items=True)


@dataclass(frozen=True)
class GraspDatasetConfig:
    """Config section ``dataset``: a grasp dataset (``dexlite dataset-add``) whose grasps train the model."""

    root: str = setting(
        "", "a grasp dataset folder (this repository's dataset/, or one of yours), relative to the checkout or absolute; the run's "
        "training objects that it holds take their grasps from it (stage dataset_grasps: every tested grasp, held or not, "
        "with its outcome) and are not optimized again; empty = not used")


@dataclass(frozen=True)
class ModelBatchConfig:
    """Config section ``model_batch``: a dataset batch made by the model (``workflow/rules/model_batch.smk``).

    Each stable object gets ``grasps_per_object`` grasps from the generator (ranked by the evaluator, refined by
    post-optimization, sections ``sample`` and ``post_optimize``); each object with fewer than ``min_distinct``
    distinct held grasps then gets batches of ``grasps_per_object`` grasps by optimization from scratch (section
    ``optimize_grasps``, its grasp types too) until it has them, ``top_up_batches`` batches were tried, or a batch added
    it no distinct held grasp. Every grasp
    is lift- and six-direction-tested, held or not, and records its source (``model`` or ``optimization``).
    """

    model: str = setting("shipped", "the generator: shipped (the package's model) or a cvae.pt file", pattern="^.+$")
    evaluator: str = setting(
        "shipped", "ranks the generator's samples: shipped (the package's evaluator), an evaluator.pt file, or none (samples not ranked)",
        pattern="^.+$")
    grasps_per_object: int = setting(64, "generator grasps per object (and grasps per top-up batch)", minimum=1)
    min_distinct: int = setting(
        30, "objects with fewer distinct held grasps from the generator get optimization from scratch (0 = never)", minimum=0)
    top_up_batches: int = setting(2, "at most this many batches of optimization from scratch per short object", minimum=0)
