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
