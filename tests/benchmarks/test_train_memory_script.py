"""benchmarks/timing/train_memory.py on a tiny run: one row per point, with the objects trained on and a peak RSS."""

import numpy as np
import pandas as pd
import pytest
import yaml

from dexlite_pipeline.io.grasp_store import write_grasp_store


@pytest.mark.slow
def test_reports_peak_memory_per_point(tmp_path, benchmark_script, hand, make_grasps, capsys):
    import trimesh

    from dexlite_pipeline.config import default_config, merge_config
    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    results = tmp_path / "run" / "results"
    objects = results / "objects"
    settings = AssetBuildSettings(sdf_resolution=24, surface_points=256)
    meshes = {"sphere": trimesh.creation.icosphere(subdivisions=2, radius=1 / 1.03), "box": trimesh.creation.box(extents=[1.2, 0.9, 0.7])}
    for object_id, mesh in meshes.items():
        write_asset(mesh, object_id, objects, settings, {"source": "test"}, convex_pieces=[mesh])
    pd.DataFrame({"object_id": ["box", "sphere"], "status": ["ok", "ok"], "split": ["train", "train"]}).to_parquet(objects / "catalog.parquet")
    (results / "stability").mkdir(parents=True)
    pd.DataFrame({"object_id": ["box", "sphere"], "stable": [True, True]}).to_parquet(results / "stability" / "stability.parquet")
    grasps = make_grasps(hand, 16, seed=7)
    grasps.arrays["lift_success"] = np.ones(16, bool)
    write_grasp_store(results / "lift" / "shard_000.zarr", grasps)
    small = {
        "device": "cpu", "scene": {"table": False},
        "train": {"batch_size": 8, "clouds_per_batch": 2, "points_per_cloud": 64, "min_grasps": 4, "validation_fraction": 0.25,
                  "energy_point_spacing_m": 0.006,
                  "model": {"pointnet_widths": [16, 32, 64, 32], "encoder_hidden": [32], "decoder_hidden": [32], "latent_dim": 8}},
    }
    config_path = tmp_path / "config.yaml"
    config_path.write_text(yaml.safe_dump(merge_config(default_config(), small)))

    script = benchmark_script("train_memory")
    assert script.main([str(tmp_path / "run"), "--configfile", str(config_path), "--counts", "1", "0", "--steps", "2", "--energies"]) == 0
    rows = [line.split("|")[1:-1] for line in capsys.readouterr().out.splitlines()[2:]]
    assert [(r[0].strip(), r[1].strip(), r[3].strip()) for r in rows] == [("1", "1", "no"), ("1", "1", "yes"), ("all", "2", "no"), ("all", "2", "yes")]
    assert all(float(r[4]) > 0.05 for r in rows)  # a torch process holds well over 50 MB
