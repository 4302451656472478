"""The objects' config types: sections ``objects`` and ``stability`` (the asset build settings: ``objects.asset_settings``).

A leaf of the config tree (``settings``): it imports no object code, so a stage's code hash
(``codehash``) covers these shapes without the computation (``objects.prepare``, ``objects.asset_building``,
``objects.build``, ``objects.stability``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from dexlite_pipeline.config import setting
from dexlite_pipeline.objects.asset_settings import AssetBuildSettings, CoacdSettings

__all__ = ["AssetBuildSettings", "CoacdSettings", "ObjectsConfig", "StabilityConfig"]


@dataclass(frozen=True)
class ObjectsConfig(CoacdSettings):
    """Config section ``objects`` (the ``coacd_*`` keys: ``CoacdSettings``)."""

    builtin_count: int = setting(40, "objects taken from pybullet_data (0 = none)", minimum=0, required=True)
    benchmark_heldout: bool = setting(
        True, "the benchmark split's objects (src/dexlite_pipeline/objects/benchmark_split.yaml) are always held out, in every "
        "profile, so every model is compared on the same objects")
    benchmark_objects: int = setting(
        4, "the first this many benchmark-split objects are added, held out: objects that no model (this run's nor the shipped "
        "one) ever trained on, where the shipped model is measured", minimum=0)
    procedural_count: int = setting(
        0, "procedural pybullet_data objects (random_urdfs, ids pb-random-NNN) to train on, in number order, the benchmark "
        "split's skipped: a campaign batch of procedural shapes (beside builtin_count's seeded draw)", minimum=0)
    procedural_first: int = setting(
        0, "procedural objects to skip first (in number order, the benchmark split's left out): a campaign batch takes "
        "procedural_first to procedural_first + procedural_count", minimum=0)
    household_count: int = setting(
        0, "generated household objects (mugs, bowls, bottles, boxes, tools; real size, metres) to train on", minimum=0)
    household_first: int = setting(
        0, "training household objects to skip first (in their round-robin order): a campaign batch takes objects "
        "household_first to household_first + household_count", minimum=0)
    household_families: tuple[str, ...] = setting(
        (), "the household families training objects are drawn from, round-robin in this order (empty: the original twelve; "
        "the shape families, plate ... toy_figure, only when named): a campaign batch for the families with the fewest grasps "
        "(ids, and so objects, do not depend on it)")
    household_variants: tuple[int, ...] = setting(
        (0,), "of each training household instance, these perturbation variants in this order (0: as generated; k >= 1: "
        "household-<family>-<NNN>-p<k>, dented, bumped, scaled, bent, noisy; objects/perturb.py): [0, 1] adds a perturbed "
        "copy after each instance, [1] draws perturbed ones only", min_items=1, unique_items=True, items={"minimum": 0})
    dataset_objects: bool = setting(
        False, "every training object of the grasp dataset at dataset.root (its objects.csv), rebuilt from its id (household "
        "generator, pybullet_data), besides the objects drawn above: a model trained on the whole dataset whatever batches "
        "made it; an object of a held-out split, or one without a rebuild recipe (a user's mesh), is left out with a warning")
    dataset_collision: bool = setting(
        True, "with dataset_objects: false prepares the dataset's training objects without collision pieces (no convex "
        "decomposition, about half of each object's preparation) and stands each in the resting pose the dataset records "
        "instead of dropping it on the table again: for runs that only train on them (training seeds, learning curves); a "
        "stage that would simulate such an object (the evaluator's examples, the ladder's training rows) records it failed, "
        "with the reason")
    household_benchmark_objects: int = setting(
        0, "the first this many objects of the household split (objects/household_split.yaml), held out", minimum=0)
    shapes_benchmark_objects: int = setting(
        0, "the first this many objects of the shapes split (objects/shapes_split.yaml: shape families and perturbed "
        "instances, never trained on), held out", minimum=0)
    mesh_dirs: tuple[str, ...] = setting((), "folders of .obj/.stl meshes to add", required=True)
    heldout_mesh_dirs: tuple[str, ...] = setting((), "folders whose meshes are always held out for evaluation", required=True)
    heldout_fraction: float = setting(0.2, "of the remaining objects, held out by a seeded split", minimum=0, maximum=1)
    heldout_yaw: bool = setting(
        True, "turn each held-out object about its z axis (up on the table) by a seeded random angle before it is prepared, so "
        "held-out rates measure grasping, not the orientation its file happened to have (catalog column turn_deg)")
    asset_cache: str = setting(
        "", "a folder of prepared assets shared by runs (e.g. ~/.cache/dexlite/assets; relative to the run folder): an asset "
        "built from the same file bytes, placement, settings and code is copied from it instead of built again, and each asset "
        "built is added to it (about 4 MB an object); empty = none")
    sdf_resolution: int = setting(96, "grid points per axis of the signed distance grid", minimum=16, maximum=256)
    sdf_padding: float = setting(0.25, "grid margin beyond the unit ball, normalized units", exclusive_minimum=0)
    sdf_exact_band: float = setting(
        0.2, "exact distance within this of the surface (normalized units; 2 cm at scale 0.1), farther out interpolated from a "
        "4x coarser exact grid (sign exact)", exclusive_minimum=0)
    surface_points: int = setting(4096, "surface samples (with normals) per object", minimum=64)

    def build_settings(self, seed: int) -> AssetBuildSettings:
        """The asset build settings this section implies (same-named fields)."""
        names = {f.name for f in dataclasses.fields(AssetBuildSettings)} - {"seed"}
        return AssetBuildSettings(**{n: getattr(self, n) for n in names}, seed=seed)


@dataclass(frozen=True)
class StabilityConfig:
    """Config section ``stability``: the PyBullet table test of ``stability_filter``."""

    scale: float = setting(0.1, "object scale in the test (normalized mesh x scale, so ~ radius in m)", exclusive_minimum=0)
    duration_s: float = setting(2.0, "simulated time", exclusive_minimum=0)
    timestep_s: float = setting(0.004166667, "physics step (PyBullet's default 1/240 s)", exclusive_minimum=0, maximum=0.05)
    tilt_deg: float = setting(
        3.0, "start tilted this much about a seeded horizontal axis (a perfectly balanced cone on its tip never falls in a "
        "perfect simulation)", minimum=0, maximum=45)
    max_lateral_m: float = setting(0.05, "stable if the centre of mass moves less than this sideways", exclusive_minimum=0)
    max_rotation_deg: float = setting(7.0, "... and the object turns less than this", exclusive_minimum=0)
    friction: float = setting(0.5, "lateral friction of object and table (rolling/spinning friction 0)", minimum=0)
    density_kg_m3: float = setting(500.0, "uniform density for mass and inertia (DexGraspNet's Isaac test: 500)", exclusive_minimum=0)
    solver_iterations: int = setting(50, "PyBullet constraint solver iterations per step", minimum=1)
    collision_margin_m: float = setting(0.0005, "contact margin of object and table shapes", minimum=0)
    settle: bool = setting(
        False, "an object that does not stand in its file orientation is dropped again from the pose it came to rest in, and "
        "used in that pose when it stands there (table column settled); off: only objects standing in their file orientation")
