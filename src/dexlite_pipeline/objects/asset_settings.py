"""How an object's asset is built: CoACD's settings and the asset build settings.

Apart from ``objects.config`` (sections ``objects`` and ``stability``) so that the code which builds an asset
(``objects.asset_building``, whose code hash keys the shared asset cache) does not depend on the other keys of
section ``objects``: adding a key there, or a way to choose objects, leaves every cached asset valid.
"""

from __future__ import annotations

from dataclasses import dataclass

from dexlite_pipeline.config import setting


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

    coacd_threshold: float = setting(
        0.08, "CoACD concavity threshold: a piece below it is split no further (DexGraspNet: 0.08; CoACD's range: 0.01-1)",
        exclusive_minimum=0, maximum=1)
    coacd_max_convex_hull: int = setting(16, "cap on convex pieces per object (-1 = no cap)", minimum=-1)
    coacd_mcts_iterations: int = setting(
        60, "CoACD search effort: tree-search iterations for each cut (its default: 150); with the nodes, depth and resolution "
        "below CoACD's defaults several times faster, so 40 objects prepare in minutes on 2 cores", minimum=1)
    coacd_mcts_nodes: int = setting(10, "child nodes the search expands per node (CoACD's default: 20)", minimum=1)
    coacd_mcts_max_depth: int = setting(2, "depth of the search: cuts looked ahead (CoACD's default: 3)", minimum=1)
    coacd_resolution: int = setting(
        1000, "surface samples CoACD uses to measure concavity, a Hausdorff distance (its default: 2000)", minimum=100)


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
