"""benchmarks/experiments/make_household_meshes.py: the check meshes in metres and in millimetres, at the sizes they name."""

import pytest
import trimesh


def test_check_mesh_script_writes_metres_and_the_millimetre_mug(tmp_path, capsys, benchmark_script):
    module = benchmark_script("make_household_meshes")
    assert module.main([str(tmp_path / "m")]) == 0
    assert module.main([str(tmp_path / "mm"), "--units", "mm"]) == 0
    assert sorted(p.name for p in (tmp_path / "m").glob("*.obj")) == ["bowl.obj", "cereal_box.obj", "mug.obj", "wine_bottle.obj"]
    load = lambda path: trimesh.load(path, force="mesh")  # noqa: E731
    mug_m = load(tmp_path / "m" / "mug.obj")
    assert mug_m.is_watertight and mug_m.extents[2] == pytest.approx(0.095)
    assert load(tmp_path / "m" / "wine_bottle.obj").extents[2] == pytest.approx(0.30)
    assert load(tmp_path / "m" / "mm" / "mug.obj").extents == pytest.approx(mug_m.extents * 1000, rel=1e-6)
    assert load(tmp_path / "mm" / "cereal_box.obj").extents == pytest.approx([200.0, 70.0, 300.0])
    assert not (tmp_path / "mm" / "mm").exists()
    assert "wine_bottle.obj: 0.075 x 0.075 x 0.3 m" in capsys.readouterr().out


def test_kitchen_set_writes_bowl_plate_spatula_hammer_lying_on_the_table(tmp_path, capsys, benchmark_script):
    module = benchmark_script("make_household_meshes")
    assert module.main([str(tmp_path), "--set", "kitchen"]) == 0
    assert sorted(p.name for p in tmp_path.glob("*.obj")) == ["bowl.obj", "hammer.obj", "plate.obj", "spatula.obj"]
    meshes = {p.stem: trimesh.load(p, force="mesh") for p in tmp_path.glob("*.obj")}
    assert all(mesh.is_watertight and mesh.bounds[0][2] == pytest.approx(0.0, abs=1e-9) for mesh in meshes.values())
    assert meshes["plate"].extents == pytest.approx([0.26, 0.26, 0.024], abs=1e-3)
    assert meshes["spatula"].extents[2] < 0.03 and meshes["hammer"].extents[2] < 0.03  # lying on the table, not standing
    assert module.main([str(tmp_path / "x"), "--set", "kitchen", "--units", "mm"]) == 2
    assert "metres only" in capsys.readouterr().err
