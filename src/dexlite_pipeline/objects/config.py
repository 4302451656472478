"""The objects' config types: sections ``objects`` and ``stability``, and the asset build settings.

A leaf of the config tree (``settings``): it imports no object code, so a stage's code hash
(``codehash``) covers these shapes without the computation (``objects.prepare``,
``objects.build``, ``objects.stability``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass


@dataclass(frozen=True)
class CoacdSettings:
    """How CoACD splits an object into the convex pieces MuJoCo and PyBullet collide (``objects.build.convex_decomposition``):
    the ``coacd_*`` keys of config section ``objects``, fields of both ``ObjectsConfig`` and ``AssetBuildSettings``.

    The defaults are config.yaml's. The concavity threshold is DexGraspNet's (CoACD's own: 0.05); at most 16 pieces
    per object (CoACD's own: no cap, -1). The search effort, 60 tree-search iterations of 10 nodes to depth 2 on 1000
    surface samples, is below CoACD's own (150, 20, 3, 2000): several times faster for a slightly less tight
    decomposition, so that 40 objects prepare in minutes on 2 cores. Everything that decomposes takes these from
    config section ``objects``: ``prepare_objects``, ``dexlite grasp`` (the package's config.yaml, under its
    ``--config-json``) and benchmarks/timing/bench_stability.py; tests lower the effort (10, 5, 1, 300) to prepare in
    seconds. The DexGraspNet import runs no CoACD: its meshes come with their pieces.
    """

    coacd_threshold: float = 0.08  # concavity below which a piece is split no further (CoACD's range: 0.01-1)
    coacd_max_convex_hull: int = 16  # pieces per object at most (-1: no cap)
    coacd_mcts_iterations: int = 60  # Monte Carlo tree-search iterations for each cut
    coacd_mcts_nodes: int = 10  # child nodes the search expands per node
    coacd_mcts_max_depth: int = 2  # depth of the search: cuts looked ahead
    coacd_resolution: int = 1000  # surface samples the concavity (a Hausdorff distance) is measured on


@dataclass(frozen=True)
class ObjectsConfig(CoacdSettings):
    """Config section ``objects`` (see config.yaml for the meaning of each key; the ``coacd_*`` keys: ``CoacdSettings``)."""

    builtin_count: int = 40
    benchmark_heldout: bool = True  # embedded objects of the benchmark split are always held out (never trained on)
    benchmark_objects: int = 4  # the first this many benchmark-split objects are added to the run, held out
    household_count: int = 0  # generated household objects (objects.household) added for training, at real size in metres
    household_benchmark_objects: int = 0  # the first this many household-split objects are added to the run, held out
    mesh_dirs: tuple[str, ...] = ()
    heldout_mesh_dirs: tuple[str, ...] = ()
    heldout_fraction: float = 0.2
    sdf_resolution: int = 96
    sdf_padding: float = 0.25
    sdf_exact_band: float = 0.2
    surface_points: int = 4096

    def build_settings(self, seed: int) -> AssetBuildSettings:
        """The asset build settings this section implies (same-named fields)."""
        names = {f.name for f in dataclasses.fields(AssetBuildSettings)} - {"seed"}
        return AssetBuildSettings(**{n: getattr(self, n) for n in names}, seed=seed)


@dataclass(frozen=True)
class AssetBuildSettings(CoacdSettings):
    """How an asset's arrays and convex pieces are made (the relevant part of the ``objects`` config:
    ``ObjectsConfig.build_settings``)."""

    sdf_resolution: int = 96
    sdf_padding: float = 0.25
    surface_points: int = 4096
    # Grid points whose distance may be within this band of the surface (normalized units)
    # get the exact distance; the rest are interpolated from a 4x coarser exact grid
    # (sign exact, error at most one coarse cell diagonal). None: exact everywhere.
    sdf_exact_band: float | None = None
    seed: int = 0


@dataclass(frozen=True)
class StabilityConfig:
    """Config section ``stability`` (see config.yaml for each key)."""

    scale: float = 0.1
    duration_s: float = 2.0
    timestep_s: float = 0.004166667
    tilt_deg: float = 3.0
    max_lateral_m: float = 0.05
    max_rotation_deg: float = 7.0
    friction: float = 0.5
    density_kg_m3: float = 500.0
    solver_iterations: int = 50
    collision_margin_m: float = 0.0005
