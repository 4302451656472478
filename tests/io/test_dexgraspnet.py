"""DexGraspNet import/export on small fixtures written here in DexGraspNet's layout (the real sample's
tests are marked real_sample: they run only where $DEXLITE_DEXGRASPNET_SAMPLE names a download)."""

import os
import pickle

import numpy as np
import pandas as pd
import pytest
from asset_checks import assert_sdf_sign_matches_pieces
from numpy.lib import format as npy_format
from sample_data import DEXGRASPNET_JOINT_KEYS, DEXGRASPNET_QPOS_ORDER

from dexlite_pipeline.cli import main as dexlite
from dexlite_pipeline.hand import JOINT_NAMES
from dexlite_pipeline.hand.qpos import qpos_from_hand_pose
from dexlite_pipeline.io.config import DexGraspNetConfig
from dexlite_pipeline.io.dexgraspnet import import_dexgraspnet, load_decomposed_mesh, object_split
from dexlite_pipeline.io.grasp_store import read_grasp_store
from dexlite_pipeline.objects.assets import load_asset, read_catalog
from dexlite_pipeline.objects.config import AssetBuildSettings

SMALL_ASSETS = AssetBuildSettings(sdf_resolution=24, sdf_padding=0.2, surface_points=256)
# Two overlapping convex boxes whose union is the box [-0.5, 0.5] x [-0.3, 0.3] x [-0.2, 0.2].
BOX_PIECES = (((-0.5, -0.3, -0.2), (0.2, 0.3, 0.2)), ((-0.1, -0.3, -0.2), (0.5, 0.3, 0.2)))
UNION_HALF_EXTENTS = np.array([0.5, 0.3, 0.2])


def _box_sdf_positive_inside(points):
    """Exact signed distance of the union box, positive inside."""
    q = np.abs(points) - UNION_HALF_EXTENTS
    outside = np.linalg.norm(np.maximum(q, 0), axis=-1)
    inside = np.minimum(q.max(axis=-1), 0)
    return -(outside + inside)


def write_decomposed_boxes(path, pieces=BOX_PIECES):
    """A CoACD-style decomposed.obj: one ``o convex_i`` group of vertices and faces per box."""
    import trimesh

    lines, offset = [], 1
    for i, (lo, hi) in enumerate(pieces):
        box = trimesh.creation.box(bounds=np.array([lo, hi]))
        lines.append(f"o convex_{i}")
        lines += [f"v {x} {y} {z}" for x, y, z in box.vertices]
        lines += [f"f {a + offset} {b + offset} {c + offset}" for a, b, c in box.faces]
        offset += len(box.vertices)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")


def random_poses(n, seed=0):
    rng = np.random.default_rng(seed)
    poses = rng.uniform(-1.0, 1.0, size=(n, 28))
    poses[:, :3] *= 0.2
    return poses


def write_grasps(root, code, entries):
    (root / "dataset").mkdir(parents=True, exist_ok=True)
    np.save(root / "dataset" / f"{code}.npy", np.array(entries, dtype=object), allow_pickle=True)


def good_entries(poses, scales):
    return [{"qpos": qpos_from_hand_pose(p), "scale": np.float64(s)} for p, s in zip(poses, scales)]


class _Malicious:
    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


@pytest.fixture()
def layout(tmp_path):
    """A DexGraspNet download with one good object, grasp-level faults, and bad files."""
    root = tmp_path / "dgn"
    poses = random_poses(6)
    scales = [0.06, 0.08, 0.1, 0.12, 0.15, 0.1]
    entries = good_entries(poses, scales)
    entries[1]["qpos"]["robot0:FFJ2"] = float("nan")
    entries[2]["qpos"]["robot0:XXJ9"] = entries[2]["qpos"].pop("robot0:LFJ4")
    entries[3]["scale"] = "0.1"
    entries.append(["not", "a", "dict"])
    entries.append({"qpos": entries[0]["qpos"], "scale": -0.1})
    write_grasps(root, "box", entries)
    write_decomposed_boxes(root / "meshdata" / "box" / "coacd" / "decomposed.obj")
    write_grasps(root, "nomesh", good_entries(random_poses(3, seed=1), [0.1] * 3))
    np.save(root / "dataset" / "numbers.npy", np.zeros((4, 28)))
    marker = tmp_path / "marker"
    with open(root / "dataset" / "evil.npy", "wb") as fp:
        npy_format.write_array_header_1_0(fp, {"descr": "|O", "fortran_order": False, "shape": (1,)})
        pickle.dump([_Malicious(marker)], fp)
    for code in ("numbers", "evil"):
        write_decomposed_boxes(root / "meshdata" / code / "coacd" / "decomposed.obj")
    return {"root": root, "poses": poses, "scales": np.array(scales), "marker": marker}


def test_import_keeps_good_grasps_and_reports_every_problem(layout, tmp_path):
    result = import_dexgraspnet(layout["root"], tmp_path / "objects", SMALL_ASSETS, DexGraspNetConfig(), seed=0)
    grasps = result.grasps
    assert not layout["marker"].exists()
    # grasps 0, 4 and 5 of box are usable
    np.testing.assert_array_equal(grasps.arrays["source_index"], [0, 4, 5])
    assert set(grasps.object_id) == {"box"} and set(grasps.arrays["source_file"]) == {"dataset/box.npy"}
    np.testing.assert_allclose(grasps.hand_pose, layout["poses"][[0, 4, 5]], rtol=1e-7, atol=1e-8)
    np.testing.assert_allclose(grasps.scale, layout["scales"][[0, 4, 5]], rtol=1e-7)

    report = {(p.file, p.grasp_index): p for p in result.problems}
    assert report[("dataset/box.npy", 1)].kind == "non_finite"
    assert report[("dataset/box.npy", 2)].kind == "unknown_joint_names" and "XXJ9" in report[("dataset/box.npy", 2)].reason
    assert report[("dataset/box.npy", 3)].kind == "wrong_type" and "scale" in report[("dataset/box.npy", 3)].reason
    assert report[("dataset/box.npy", 6)].kind == "wrong_type"
    assert report[("dataset/box.npy", 7)].kind == "bad_scale"
    assert report[("dataset/nomesh.npy", -1)].kind == "missing_mesh"
    assert report[("dataset/nomesh.npy", -1)].grasps_affected == 3
    assert report[("dataset/numbers.npy", -1)].kind == "wrong_type"
    evil = report[("dataset/evil.npy", -1)]
    assert evil.kind == "refused_pickle" and "system" in evil.reason
    assert len(result.problems) == 8

    catalog = {row["object_id"]: row for row in result.catalog}
    assert catalog["box"]["status"] == "ok" and catalog["box"]["n_convex_pieces"] == 2 and catalog["box"]["watertight"]
    assert catalog["box"]["volume"] == pytest.approx(np.prod(2 * UNION_HALF_EXTENTS), rel=1e-6)
    assert {catalog[c]["status"] for c in ("nomesh", "numbers", "evil")} == {"rejected"}
    assert sorted(p.name for p in (tmp_path / "objects" / "assets").iterdir()) == ["box"]


def test_import_on_worker_processes_equals_in_process(layout, tmp_path):
    serial = import_dexgraspnet(layout["root"], tmp_path / "serial", SMALL_ASSETS, DexGraspNetConfig(), seed=0)
    pooled = import_dexgraspnet(layout["root"], tmp_path / "pooled", SMALL_ASSETS, DexGraspNetConfig(), seed=0, workers=2)
    np.testing.assert_array_equal(serial.grasps.hand_pose, pooled.grasps.hand_pose)
    assert serial.problems == pooled.problems
    assert [(r["object_id"], r["status"]) for r in serial.catalog] == [(r["object_id"], r["status"]) for r in pooled.catalog]
    box = "assets/box/arrays.zarr"
    assert sorted(p.name for p in (tmp_path / "pooled" / box).iterdir()) == sorted(p.name for p in (tmp_path / "serial" / box).iterdir())


def test_union_of_pieces_gives_the_solids_sdf_and_outer_surface(layout, tmp_path):
    mesh, pieces = load_decomposed_mesh(layout["root"] / "meshdata" / "box" / "coacd" / "decomposed.obj")
    assert len(pieces) == 2 and mesh.is_watertight
    import_dexgraspnet(layout["root"], tmp_path / "objects", SMALL_ASSETS, DexGraspNetConfig(), seed=0)
    asset = load_asset(tmp_path / "objects", "box")
    g = asset.sdf.shape[0]
    axis = np.arange(g) * asset.voxel_size
    grid = np.stack(np.meshgrid(*(axis + asset.grid_min[i] for i in range(3)), indexing="ij"), axis=-1)
    expected = _box_sdf_positive_inside(grid)
    # exact at grid points, including the pieces' internal faces at x = -0.1 and x = 0.2
    np.testing.assert_allclose(asset.sdf, expected, atol=1e-5)
    assert asset.sdf[np.abs(grid[..., 0] - 0.2) < asset.voxel_size].max() > 0.15
    # surface samples lie on the outer boundary only, with outward normals
    np.testing.assert_allclose(_box_sdf_positive_inside(asset.surface_points), 0.0, atol=1e-6)
    assert (np.einsum("ij,ij->i", asset.surface_points, asset.surface_normals) > 0).all()


def test_a_crashed_file_counts_its_grasps_from_the_header_or_says_unknown(layout, tmp_path, monkeypatch, capsys):
    """A worker that dies takes all of its file's grasps with it; the report and the summary must not say none were lost."""
    from dexlite_pipeline.io import dexgraspnet

    (layout["root"] / "dataset" / "garbled.npy").write_bytes(b"not an npy file")

    def crash(path, root):
        raise RuntimeError("simulated native crash")

    monkeypatch.setattr(dexgraspnet, "read_grasp_file", crash)
    out = tmp_path / "grasps.zarr"
    code = dexlite(["import-dexgraspnet", str(layout["root"]), "--out", str(out), *_import_outputs(tmp_path / "objects", tmp_path / "grasps.import_report.csv"), "--threads", "1"])
    assert code == 0
    report = pd.read_csv(tmp_path / "grasps.import_report.csv").set_index("file")
    assert set(report["kind"]) == {"import_failed"}
    # Grasp files are 1-D arrays of dicts; a header that cannot be read or declares another shape says nothing of grasps.
    counts = {"dataset/box.npy": 8, "dataset/evil.npy": 1, "dataset/garbled.npy": -1, "dataset/nomesh.npy": 3, "dataset/numbers.npy": -1}
    assert report["grasps_affected"].to_dict() == counts
    attrs = read_grasp_store(out).attrs
    assert attrs["grasps_not_imported"] == 12 and attrs["failed_files_with_unknown_grasp_count"] == 2
    assert "12 grasps (plus the grasps of 2 failed files, number unknown)" in capsys.readouterr().out


def test_export_then_import_round_trip(layout, tmp_path):
    first = import_dexgraspnet(layout["root"], tmp_path / "objects", SMALL_ASSETS, DexGraspNetConfig(), seed=0).grasps
    from dexlite_pipeline.io.grasp_store import write_grasp_store

    assert "grasp_type" not in first.arrays  # a DexGraspNet download: power grasps, a store without the array
    first.arrays["grasp_type"] = np.resize(np.asarray(["pinch", "power", "tripod"], dtype=object), len(first))
    write_grasp_store(tmp_path / "first.zarr", first)
    assert dexlite(["export-dexgraspnet", str(tmp_path / "first.zarr"), "--out", str(tmp_path / "out"), "--objects", str(tmp_path / "objects")]) == 0
    exported = np.load(tmp_path / "out" / "dataset" / "box.npy", allow_pickle=True)  # our own file
    assert set(exported[0]) == {"qpos", "scale", "grasp_type"}
    assert [e["grasp_type"] for e in exported] == first.arrays["grasp_type"][first.object_id == "box"].tolist()
    original = np.load(layout["root"] / "dataset" / "box.npy", allow_pickle=True)
    for entry, index in zip(exported, [0, 4, 5]):
        for key, value in original[index]["qpos"].items():
            assert entry["qpos"][key] == pytest.approx(value, rel=1e-7, abs=1e-8)
        assert entry["scale"] == pytest.approx(float(original[index]["scale"]), rel=1e-7)
    second = import_dexgraspnet(tmp_path / "out", tmp_path / "objects2", SMALL_ASSETS, DexGraspNetConfig(), seed=0)
    assert second.problems == []
    np.testing.assert_array_equal(second.grasps.hand_pose, first.hand_pose)
    np.testing.assert_array_equal(second.grasps.scale, first.scale)
    assert list(second.grasps.object_id) == list(first.object_id)
    assert second.grasps.arrays["grasp_type"].tolist() == first.arrays["grasp_type"].tolist()  # the types come back
    np.testing.assert_allclose(load_asset(tmp_path / "objects2", "box").sdf, load_asset(tmp_path / "objects", "box").sdf, atol=1e-5)


def _import_outputs(objects_dir, report):
    """The import's catalog (assets beside it) and report options."""
    return ["--catalog", str(objects_dir / "catalog.parquet"), "--report", str(report)]


def test_cli_writes_store_catalog_and_report(layout, tmp_path):
    config = '{"seed": 3, "objects": {"sdf_resolution": 24, "surface_points": 256}, "dexgraspnet": {"heldout_object_codes": ["box"]}}'
    out = tmp_path / "res" / "grasps.zarr"
    code = dexlite(["import-dexgraspnet", str(layout["root"]), "--out", str(out), *_import_outputs(tmp_path / "res" / "objects", tmp_path / "res" / "grasps.import_report.csv"), "--config-json", config])
    assert code == 0
    grasps = read_grasp_store(out)
    assert len(grasps) == 3 and grasps.attrs["grasps_imported"] == 3 and grasps.attrs["config"]["seed"] == 3
    assert grasps.attrs["grasps_not_imported"] == 5 + 3
    report = pd.read_csv(tmp_path / "res" / "grasps.import_report.csv")
    assert len(report) == 8 and set(report["kind"]) >= {"refused_pickle", "missing_mesh", "unknown_joint_names", "non_finite", "wrong_type"}
    catalog = read_catalog(tmp_path / "res" / "objects")
    assert list(catalog.columns) == ["object_id", "source", "file", "watertight", "volume", "n_convex_pieces", "status", "reason",
                                     "preparation", "surface_deviation", "bounds_deviation", "volume_ratio", "turn_deg", "split"]
    assert set(catalog.loc[catalog["status"] == "ok", "preparation"]) == {"imported as given (DexGraspNet's mesh and convex pieces)"}
    assert catalog.set_index("object_id").loc["box", "split"] == "heldout"
    assert load_asset(tmp_path / "res" / "objects", "box").sdf.shape == (24, 24, 24)


def test_export_reports_missing_assets_and_refuses_unsafe_ids(tmp_path, capsys):
    from dexlite_pipeline.io.grasp_store import GraspSet, write_grasp_store

    poses = random_poses(2).astype(np.float32)
    ok = GraspSet({"hand_pose": poses, "object_id": np.array(["mug", "mug"], dtype=object), "scale": np.full(2, 0.1, np.float32)})
    write_grasp_store(tmp_path / "ok.zarr", ok)
    assert dexlite(["export-dexgraspnet", str(tmp_path / "ok.zarr"), "--out", str(tmp_path / "out"), "--objects", str(tmp_path / "none")]) == 0
    assert "no prepared asset (mesh not exported) for: mug" in capsys.readouterr().out
    assert (tmp_path / "out" / "dataset" / "mug.npy").is_file() and not (tmp_path / "out" / "meshdata").exists()
    unsafe = GraspSet({**ok.arrays, "object_id": np.array(["mug", "../mug"], dtype=object)})
    write_grasp_store(tmp_path / "unsafe.zarr", unsafe)
    assert dexlite(["export-dexgraspnet", str(tmp_path / "unsafe.zarr"), "--out", str(tmp_path / "out2")]) == 2
    assert "cannot be used as a DexGraspNet file name" in capsys.readouterr().err
    assert not (tmp_path / "out2").exists()


def test_exporting_an_empty_store_fails(tmp_path, capsys):
    from dexlite_pipeline.io.grasp_store import empty_grasp_set, write_grasp_store

    write_grasp_store(tmp_path / "empty.zarr", empty_grasp_set())
    assert dexlite(["export-dexgraspnet", str(tmp_path / "empty.zarr"), "--out", str(tmp_path / "out")]) == 2
    assert f"{tmp_path / 'empty.zarr'}: the grasp store is empty, nothing to export" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_missing_dataset_folder_is_a_clear_error(tmp_path, capsys):
    code = dexlite(["import-dexgraspnet", str(tmp_path), "--out", str(tmp_path / "g.zarr"), *_import_outputs(tmp_path / "o", tmp_path / "r.csv")])
    assert code == 2 and "dataset: no such folder" in capsys.readouterr().err


def test_split_is_seeded_per_object_and_honours_the_heldout_list():
    codes = [f"obj{i}" for i in range(400)]
    config = DexGraspNetConfig(heldout_fraction=0.25, heldout_object_codes=("obj7",))
    splits = [object_split(c, config, seed=1) for c in codes]
    assert splits == [object_split(c, config, seed=1) for c in codes]
    assert 0.18 < splits.count("heldout") / len(codes) < 0.32 and splits[7] == "heldout"
    assert splits != [object_split(c, config, seed=2) for c in codes]
    assert {object_split(c, DexGraspNetConfig(), seed=1) for c in codes} == {"train"}


@pytest.fixture(scope="module")
def imported_sample(dexgraspnet_sample, tmp_path_factory):
    """The real sample imported once at a coarse grid (the result, and its objects dir)."""
    objects = tmp_path_factory.mktemp("sample_objects")
    settings = AssetBuildSettings(sdf_resolution=40, sdf_padding=0.2, surface_points=2000)
    return import_dexgraspnet(dexgraspnet_sample, objects, settings, DexGraspNetConfig(), seed=0), objects


@pytest.mark.real_sample
def test_real_sample_imports_whole_with_correct_sdf_sign(dexgraspnet_sample, imported_sample):
    import trimesh

    result, objects = imported_sample
    assert len(result.grasps) == 494 and result.problems == []
    rng = np.random.default_rng(0)
    for object_id in sorted(set(result.grasps.object_id)):
        asset = load_asset(objects, object_id)
        soup = trimesh.load(dexgraspnet_sample / "meshdata" / object_id / "coacd" / "decomposed.obj", force="mesh", process=False)
        assert_sdf_sign_matches_pieces(asset, soup, rng)


@pytest.mark.real_sample
def test_real_sample_grasps_barely_penetrate(imported_sample):
    """The makers filtered these grasps at 1 mm: a frame or conversion error shows up as deep penetration."""
    from dexlite_pipeline.energy.per_grasp import evaluate_grasp_energies

    result, objects = imported_sample
    penetration_mm = evaluate_grasp_energies(result.grasps, [objects])["penetration_mm"]
    assert np.median(penetration_mm) <= 1.5
    # control: the same grasps with the four fingers closed through the object
    closed = result.grasps.select(np.arange(0, 494, 8))
    finger_flexion = [6 + i for i, name in enumerate(JOINT_NAMES) if name[-2:] in ("J2", "J1", "J0") and "TH" not in name]
    assert len(finger_flexion) == 12
    closed.arrays["hand_pose"] = closed.hand_pose.copy()
    closed.hand_pose[:, finger_flexion] = 1.571
    assert np.median(evaluate_grasp_energies(closed, [objects])["penetration_mm"]) > 3.0


@pytest.mark.real_sample
def test_real_sample_force_closure_on_threads_equals_serial(imported_sample):
    """Real grasps give a mix of closing and open contact sets, and the threaded hull step changes nothing."""
    from dexlite_pipeline.curation.force_closure import evaluate_force_closure

    result, objects = imported_sample
    grasps = result.grasps.select(np.arange(0, 494, 12))
    serial = evaluate_force_closure(grasps, [objects], batch_size=16).epsilon
    threaded = evaluate_force_closure(grasps, [objects], batch_size=16, threads=2).epsilon
    np.testing.assert_array_equal(serial, threaded)
    assert 0.2 < float((serial > 0).mean()) < 1.0


def write_dexgraspnet_file(root, code, count, seed=0):
    """A grasp file in DexGraspNet's own structure (``sample_data.DEXGRASPNET_QPOS_ORDER``, Python
    float values, numpy float64 scales) and a decomposed box mesh; returns (qpos dicts, scales)."""
    rng = np.random.default_rng(seed)
    qposes, scales, entries = [], [], []
    for _ in range(count):
        values = {key: float(rng.uniform(0.0, 1.2)) for key in DEXGRASPNET_JOINT_KEYS}
        values |= {key: float(rng.uniform(-np.pi, np.pi)) for key in ("WRJRx", "WRJRy", "WRJRz")}
        values |= {key: float(rng.uniform(-0.2, 0.2)) for key in ("WRJTx", "WRJTy", "WRJTz")}
        qpos = {key: values[key] for key in DEXGRASPNET_QPOS_ORDER}
        scale = np.float64(rng.choice([0.06, 0.08, 0.1, 0.12, 0.15]))
        qposes.append(qpos)
        scales.append(scale)
        entries.append({"qpos": qpos, "scale": scale})
    write_grasps(root, code, entries)
    write_decomposed_boxes(root / "meshdata" / code / "coacd" / "decomposed.obj")
    return qposes, np.asarray(scales)


def assert_dexgraspnet_structure(path):
    """``path`` is a grasp file as DexGraspNet writes it: keys, key order and value types (our export adds each grasp's
    ``grasp_type`` after them, a string)."""
    entries = np.load(path, allow_pickle=True)
    assert entries.dtype == object and entries.ndim == 1 and len(entries) > 0
    for entry in entries:
        assert type(entry) is dict and list(entry) in (["qpos", "scale"], ["qpos", "scale", "grasp_type"])
        assert type(entry.get("grasp_type", "")) is str
        assert list(entry["qpos"]) == list(DEXGRASPNET_QPOS_ORDER)
        assert all(type(value) is float for value in entry["qpos"].values())
        assert type(entry["scale"]) is np.float64
    return entries


def test_a_file_in_dexgraspnets_own_structure_imports_exactly(tmp_path):
    qposes, scales = write_dexgraspnet_file(tmp_path / "dgn", "core-box-0", 5)
    result = import_dexgraspnet(tmp_path / "dgn", tmp_path / "objects", SMALL_ASSETS, DexGraspNetConfig(), seed=0)
    assert result.problems == [] and len(result.grasps) == 5
    # hand_pose is [palm translation, palm Euler angles, the 22 joints]
    expected = [[q[k] for k in ("WRJTx", "WRJTy", "WRJTz", "WRJRx", "WRJRy", "WRJRz", *JOINT_NAMES)] for q in qposes]
    assert sorted(JOINT_NAMES) == sorted(DEXGRASPNET_JOINT_KEYS)
    np.testing.assert_allclose(result.grasps.hand_pose, expected, rtol=1e-7, atol=1e-8)
    np.testing.assert_allclose(result.grasps.scale, scales, rtol=1e-7)


def test_cli_round_trip_export_then_import_keeps_dexgraspnets_structure(tmp_path):
    """import-dexgraspnet, export-dexgraspnet, import-dexgraspnet: the export is DexGraspNet's structure
    with the original values, and importing it again gives the same grasps and the same object."""
    qposes, scales = write_dexgraspnet_file(tmp_path / "dgn", "core-box-0", 6, seed=1)
    small = '{"objects": {"sdf_resolution": 24, "surface_points": 256}}'

    def cli_import(root, name):
        out = tmp_path / name
        code = dexlite(["import-dexgraspnet", str(root), "--out", str(out / "grasps.zarr"),
                        *_import_outputs(out / "objects", out / "report.csv"), "--config-json", small])
        assert code == 0
        return read_grasp_store(out / "grasps.zarr"), out / "objects"

    first, first_objects = cli_import(tmp_path / "dgn", "first")
    assert dexlite(["export-dexgraspnet", str(tmp_path / "first" / "grasps.zarr"), "--out", str(tmp_path / "exported"), "--objects", str(first_objects)]) == 0

    exported = assert_dexgraspnet_structure(tmp_path / "exported" / "dataset" / "core-box-0.npy")
    for entry, qpos, scale in zip(exported, qposes, scales, strict=True):
        np.testing.assert_allclose([entry["qpos"][k] for k in DEXGRASPNET_QPOS_ORDER], [qpos[k] for k in DEXGRASPNET_QPOS_ORDER], rtol=1e-6, atol=1e-7)
        assert entry["scale"] == pytest.approx(scale, rel=1e-7)
    mesh_text = (tmp_path / "exported" / "meshdata" / "core-box-0" / "coacd" / "decomposed.obj").read_text()
    assert mesh_text.startswith("o convex_0\n") and mesh_text.count("\no convex_") == 1  # the two pieces, in CoACD's layout

    second, second_objects = cli_import(tmp_path / "exported", "second")
    assert pd.read_csv(tmp_path / "second" / "report.csv").empty
    np.testing.assert_array_equal(second.hand_pose, first.hand_pose)
    np.testing.assert_array_equal(second.scale, first.scale)
    assert list(second.object_id) == list(first.object_id) == ["core-box-0"] * 6
    np.testing.assert_allclose(load_asset(second_objects, "core-box-0").sdf, load_asset(first_objects, "core-box-0").sdf, atol=1e-5)
