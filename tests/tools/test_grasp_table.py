"""``dexlite grasp`` on a table: which pose each mesh stands in (stable pose, a given upright axis, or floating)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from dexlite_pipeline.objects.assets import load_asset
from dexlite_pipeline.objects.build import AssetBuildSettings, write_asset
from dexlite_pipeline.objects.asset_building import normalize_mesh
from dexlite_pipeline.objects.config import StabilityConfig
from dexlite_pipeline.tabletop import UPRIGHT_AXES, tool_support_planes


@pytest.fixture(scope="module")
def assets(tmp_path_factory):
    """A flat box (stands as it is) and a thin rod standing on its end (topples onto its side), normalized."""
    root = tmp_path_factory.mktemp("tool_objects")
    settings = AssetBuildSettings(sdf_resolution=16, surface_points=64)
    meshes = {"flat_box": trimesh.creation.box((1.0, 0.8, 0.3)), "rod": trimesh.creation.cylinder(0.015, 1.0, sections=16)}
    for object_id, mesh in meshes.items():
        mesh = normalize_mesh(mesh)[0]
        write_asset(mesh, object_id, root, settings, {"source": "test"}, convex_pieces=[mesh])
    return [load_asset(root, oid) for oid in meshes]


def test_stable_pose_is_where_each_mesh_comes_to_rest(assets):
    planes, said = tool_support_planes(assets, True, None, StabilityConfig(), seed=0)
    box, rod = (np.asarray(planes.get(a.object_id).normal) for a in assets)
    assert box[2] > math.cos(math.radians(5)) and "stands as in the file" in said["flat_box"]
    assert abs(rod[2]) < math.cos(math.radians(45)) and "topples" in said["rod"]  # lies on its side
    for asset in assets:
        heights = np.asarray(asset.load_mesh().vertices) @ np.asarray(planes.get(asset.object_id).normal) + planes.get(asset.object_id).offset
        assert heights.min() == pytest.approx(0.0, abs=1e-9)


def test_a_given_upright_axis_and_floating_mode(assets):
    planes, said = tool_support_planes(assets, True, "-x", StabilityConfig(), seed=0)
    assert planes.get("rod").normal == (-1.0, 0.0, 0.0) and "-x axis up" in said["rod"]
    assert tool_support_planes(assets, False, None, StabilityConfig(), seed=0)[0] is None
    with pytest.raises(ValueError, match="upright axis"):
        tool_support_planes(assets, True, "up", StabilityConfig(), seed=0)
    assert set(UPRIGHT_AXES) == {"+x", "-x", "+y", "-y", "+z", "-z"}


def test_cli_refuses_an_unknown_upright_axis(tmp_path, capsys):
    from dexlite_pipeline.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["grasp", str(tmp_path), "--out", str(tmp_path / "out"), "--upright-axis", "up"])
    assert exit_info.value.code == 2 and "--upright-axis" in capsys.readouterr().err
