"""A tiny optimization from scratch of power grasps, for the check that power grasps stay what they were.

``power_run`` optimizes three starts at each of two scales of a box standing on its table, once with the run's
generator in batch order (the ``optimize_grasps`` stage) and once keyed by object and start (``dexlite grasp``),
with every phase on: contact switches, contact searches during the run and after it, a hopeless-stop checkpoint
and contact resolution. ``python tests/optim/power_baseline.py OUT.npz OBJECTS_DIR`` writes its arrays; the
fixture ``tests/fixtures/power_baseline.npz`` was written so by the code before grasp types existed, and
``test_grasp_types.py`` compares a power-only run of today's code with it (the starts bit for bit, the optimized
grasps to float rounding, which another CPU does otherwise).
"""

from __future__ import annotations

import sys

import numpy as np

ARRAYS = ("hand_pose", "init_pose", "contact_index", "E_total", "stopped_at_iteration")


def power_settings():
    """The tiny run's ``optimize_grasps`` settings (power grasps only, the default mix)."""
    from dexlite_pipeline.optim.config import AnnealingSchedule, HopelessStopConfig, InitConfig, OptimizeGraspsConfig

    return OptimizeGraspsConfig(
        grasps_per_object=3, scales=(0.08, 0.1), batch_size=4, init=InitConfig(distance_m=(0.05, 0.08)),
        annealing=AnnealingSchedule(iterations=40, step_size_period=17, temperature_period=10), trace_every=10,
        final_contact_samples=16, contact_search_every=10,
        stop_hopeless=HopelessStopConfig(iterations=(20,), max_e_fc=(4.0,), max_e_dis_m=(0.05,)),
    )


def power_run(objects_dir) -> dict[str, np.ndarray]:
    """The tiny run's arrays, ``<name>`` from the generator in batch order and ``keyed_<name>`` from keyed streams."""
    import torch

    from dexlite_pipeline.energy.config import EnergyConfig
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.objects.rest_pose import SupportPlane
    from dexlite_pipeline.optim.from_scratch import synthesize
    from dexlite_pipeline.tabletop import SupportPlanes

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        assets = [load_asset(objects_dir, "box")]
        planes = SupportPlanes({"box": SupportPlane((0.0, 0.0, 1.0), 0.3)})
        energy = EnergyConfig(object_point_spacing_m=0.004)
        stage, _ = synthesize(assets, power_settings(), energy, torch.Generator().manual_seed(11), support_planes=planes)
        keyed, _ = synthesize(assets, power_settings(), energy, torch.Generator().manual_seed(11), support_planes=planes, keyed_seed=5)
    finally:
        torch.set_num_threads(threads)
    return {**{k: stage.arrays[k] for k in ARRAYS}, **{f"keyed_{k}": keyed.arrays[k] for k in ARRAYS}}


def tiny_box_objects(root):
    """The box of ``tests/optim/conftest.py``'s ``optim_objects`` (extents 1.2 x 0.8 x 0.6), prepared into ``root``."""
    import trimesh

    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    settings = AssetBuildSettings(sdf_resolution=32, sdf_padding=0.3, surface_points=800)
    mesh = trimesh.creation.box(extents=(1.2, 0.8, 0.6))
    write_asset(mesh, "box", root, settings, {"source": "test"}, convex_pieces=[mesh])
    return root


if __name__ == "__main__":
    from pathlib import Path

    out, objects = Path(sys.argv[1]), Path(sys.argv[2])
    objects.mkdir(parents=True, exist_ok=True)
    np.savez(out, **power_run(tiny_box_objects(objects)))
