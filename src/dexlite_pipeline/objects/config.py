"""The objects' config types: sections ``objects`` and ``stability``, and the asset build settings.

A leaf of the config tree (``settings``): it imports no object code, so a stage's code hash
(``codehash``) covers these shapes without the computation (``objects.prepare``,
``objects.build``, ``objects.stability``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass


@dataclass(frozen=True)
class ObjectsConfig:
    """Config section ``objects`` (see config.yaml for the meaning of each key)."""

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
    coacd_threshold: float = 0.08
    coacd_max_convex_hull: int = 16
    coacd_mcts_iterations: int = 60
    coacd_mcts_nodes: int = 10
    coacd_mcts_max_depth: int = 2
    coacd_resolution: int = 1000

    def build_settings(self, seed: int) -> AssetBuildSettings:
        """The asset build settings this section implies (same-named fields)."""
        names = {f.name for f in dataclasses.fields(AssetBuildSettings)} - {"seed"}
        return AssetBuildSettings(**{n: getattr(self, n) for n in names}, seed=seed)


@dataclass(frozen=True)
class AssetBuildSettings:
    """How an asset's arrays are made (the relevant part of the ``objects`` config)."""

    sdf_resolution: int = 96
    sdf_padding: float = 0.25
    surface_points: int = 4096
    coacd_threshold: float = 0.08
    coacd_max_convex_hull: int = 16
    # CoACD search effort (its defaults: 150 iterations, 20 nodes, depth 3, 2000 samples):
    # lower values trade a slightly less tight decomposition for a several-fold speed-up.
    coacd_mcts_iterations: int = 150
    coacd_mcts_nodes: int = 20
    coacd_mcts_max_depth: int = 3
    coacd_resolution: int = 2000
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
