"""``dexlite grasp``: from mesh files made here to held grasps, stores, export, pictures and a summary."""

from __future__ import annotations

import dataclasses
import json
import logging

import numpy as np
import pytest
import trimesh

from dexlite_pipeline.cli import main
from dexlite_pipeline.io.grasp_store import read_grasp_store

# Small grids, a light CoACD search and a short optimization: a budget for tests, not for use.
TINY = {
    "objects": {"sdf_resolution": 32, "surface_points": 512, "coacd_mcts_iterations": 10, "coacd_mcts_nodes": 5,
                "coacd_mcts_max_depth": 1, "coacd_resolution": 300},
    "energy": {"object_point_spacing_m": 0.004},
    "optimize_grasps": {"annealing": {"iterations": 60}, "final_contact_samples": 32, "contact_search_every": 0},
    "post_optimize": {"annealing": {"iterations": 5}, "energy_point_spacing_m": 0.004, "start_contact_samples": 8, "final_contact_samples": 8},
}  # fmt: skip


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    """An 8 x 6 x 10 cm box (.obj) and an open-bottomed cylinder of 7 cm diameter (.stl), in metres."""
    folder = tmp_path_factory.mktemp("meshes")
    trimesh.creation.box((0.08, 0.06, 0.10)).export(folder / "box.obj")
    cylinder = trimesh.creation.cylinder(radius=0.035, height=0.09, sections=32)
    bottom = cylinder.face_normals[:, 2] < -0.99
    trimesh.Trimesh(cylinder.vertices, cylinder.faces[~bottom], process=False).export(folder / "cup.stl")
    return folder


@pytest.fixture(scope="module")
def grasp_run(meshes, tmp_path_factory):
    out = tmp_path_factory.mktemp("grasp") / "out"
    code = main(["grasp", str(meshes), "--out", str(out), "--n", "2", "--renders", "1", "--threads", "2",
                 "--from-scratch", "--config-json", json.dumps(TINY)])  # fmt: skip
    return code, out


@pytest.mark.slow
def test_grasp_writes_every_output_for_an_obj_and_an_stl(grasp_run):
    code, out = grasp_run
    every = read_grasp_store(out / "all_grasps.zarr")
    held = read_grasp_store(out / "grasps.zarr")
    assert sorted(set(every.object_id)) == ["user-box", "user-cup"]
    assert [int((every.object_id == o).sum()) for o in ("user-box", "user-cup")] == [2, 2]
    lifted = np.asarray(every.arrays["lift_success"], bool)
    labels = np.asarray(every.arrays["distinct_label"])
    assert ((labels >= 0) == lifted).all()
    assert len(held) == len({(o, int(l)) for o, l in zip(every.object_id[lifted], labels[lifted])})  # one per distinct grasp
    assert code == (0 if len(held) else 1)
    for name in ("hand_pose", "object_id", "scale", "lift_success", "failure_reason", "six_dir_success", "six_dir_passed", "E_fc", "E_pen", "distinct_label"):
        assert name in held.arrays and name in every.arrays
    assert held.hand_pose.shape[1:] == (28,)
    assert (np.asarray(every.arrays["initial_penetration_mm"])[lifted] <= 2.0 + 1e-4).all()  # the start cap (2 mm) holds for every held grasp
    for object_id in set(held.object_id):
        assert (out / "dexgraspnet" / "dataset" / f"{object_id}.npy").is_file()
        assert (out / "dexgraspnet" / "meshdata" / object_id / "coacd" / "decomposed.obj").is_file()
    renders = sorted(p.name for p in (out / "renders").glob("*.png"))
    assert [name.split("_")[0] for name in renders] == ["user-box", "user-cup"]
    summary = (out / "summary.md").read_text()
    assert "| user-box | box.obj | 6 x 8 x 10 cm |" in summary and "| user-cup | cup.stl | 6.97 x 6.97 x 9 cm |" in summary
    assert f"{int(lifted.sum())}/4 (" in summary and "six-direction" in summary
    for name in renders:
        assert f"renders/{name}" in summary
    assert "| surface touched |" in summary
    # how each mesh became its solid, with its deviation from the mesh (the cup's open bottom filled: one-sided surface)
    assert "- user-box: single shell of 1 body; prepared solid vs the mesh: surface p99 0.00% / 0.00%, box 0.00%, volume 100.0%" in summary
    assert "- user-cup: " in summary and "prepared solid vs the mesh: surface p99 " in summary
    for object_id in ("user-box", "user-cup"):  # a percentage where the object has held grasps, 0% where none held
        row = next(line for line in summary.splitlines() if line.startswith(f"| {object_id} |"))
        deepest, touched = row.split("|")[7].strip(), row.split("|")[8].strip()
        assert deepest == "-" or float(deepest) <= 2.0, row  # the deepest start of a held grasp, within the cap
        assert touched.endswith("%") and (touched != "0%") == bool((lifted & (every.object_id == object_id)).any()), row
    view = out / "view.html"
    assert view.is_file() == bool(len(held)) and (("`view.html`" in summary) == bool(len(held)))
    if len(held):
        assert "plotly" in view.read_text()[:200000] and str(held.object_id[0]) in view.read_text()


@pytest.mark.slow
def test_grasps_are_for_the_object_at_its_real_size(grasp_run):
    _, out = grasp_run
    every = read_grasp_store(out / "all_grasps.zarr")
    # Normalized objects have radius 1 / 1.03, so the scale that restores the box is 1.03 x its half-diagonal.
    box = every.scale[every.object_id == "user-box"]
    assert np.allclose(box, 1.03 * np.linalg.norm([0.04, 0.03, 0.05]), rtol=1e-5)
    cup = every.scale[every.object_id == "user-cup"]
    assert np.allclose(cup, 1.03 * np.hypot(0.035, 0.045), rtol=1e-3)


def _untrained_model(path):
    """A small CVAE with untrained weights saved as ``path``: a model file for testing the plumbing, not the grasps."""
    from dexlite_pipeline.model.checkpoint import save_checkpoint
    from dexlite_pipeline.model.config import ModelConfig
    from dexlite_pipeline.model.network import GraspCVAE

    @dataclasses.dataclass
    class Trained:
        points_per_cloud: int = 64

    path.parent.mkdir(parents=True, exist_ok=True)
    small = ModelConfig(pointnet_widths=(16, 32), encoder_hidden=(32,), decoder_hidden=(32,), latent_dim=8, normalization="none")
    save_checkpoint(path, GraspCVAE(small), Trained(), {"seed": 0})
    return path


@pytest.mark.slow
def test_grasp_with_a_model_samples_and_post_optimizes(grasp_run, meshes, tmp_path):
    """A trained model's path; with --min-distinct 0 its grasps only, whatever they give."""
    model = _untrained_model(tmp_path / "cvae.pt")
    out = tmp_path / "with_model"
    code = main(["grasp", str(meshes / "box.obj"), "--out", str(out), "--n", "3", "--renders", "0", "--threads", "1",
                 "--model", str(model), "--resize-to-training", "--min-distinct", "0", "--config-json", json.dumps(TINY)])  # fmt: skip
    every = read_grasp_store(out / "all_grasps.zarr")
    assert len(every) == 3 and set(every.arrays["method"]) == {"cvae_post"} and set(every.arrays["source"]) == {"model"}
    assert "raw_hand_pose" in every.arrays and np.isfinite(every.hand_pose).all()
    assert sorted(set(np.round(every.scale, 3))) == [0.08, 0.1, 0.12]
    assert code == (0 if every.arrays["lift_success"].any() else 1)
    assert every.attrs["min_distinct"] == 0 and every.attrs["topped_up"] == []
    summary = (out / "summary.md").read_text()
    assert "`--min-distinct 0`: the model's grasps only; optimization from scratch never tops them up." in summary


@pytest.mark.slow
def test_a_model_path_on_more_meshes_than_a_group_refines_them_group_by_group(meshes, tmp_path, caplog, monkeypatch):
    """post_optimize.objects_per_energy 1: each mesh's samples refined with an energy of that mesh alone, every mesh its grasps."""
    from dexlite_pipeline.energy.grasp_energy import GraspEnergy

    built = []
    original = GraspEnergy.from_assets.__func__

    def recording(cls, hand, assets, *args, **kwargs):
        built.append(sorted(a.object_id for a in assets))
        return original(cls, hand, assets, *args, **kwargs)

    monkeypatch.setattr(GraspEnergy, "from_assets", classmethod(recording))
    config = {**TINY, "post_optimize": {**TINY["post_optimize"], "objects_per_energy": 1}}
    out = tmp_path / "grouped"
    with caplog.at_level(logging.INFO):
        main(["grasp", str(meshes), "--out", str(out), "--n", "2", "--renders", "0", "--threads", "1", "--model",
              str(_untrained_model(tmp_path / "cvae.pt")), "--resize-to-training", "--min-distinct", "0", "--config-json", json.dumps(config)])
    every = read_grasp_store(out / "all_grasps.zarr")
    assert sorted(every.object_id.tolist()) == ["user-box"] * 2 + ["user-cup"] * 2 and np.isfinite(every.hand_pose).all()
    assert ["user-box", "user-cup"] not in built and ["user-box"] in built and ["user-cup"] in built
    assert "objects 1-1 of 2 refined" in caplog.text and "objects 2-2 of 2 refined" in caplog.text


def _untrained_evaluator(path):
    """A small grasp evaluator with untrained weights saved as ``path``: for testing the ranking's plumbing."""
    from dexlite_pipeline.model.evaluator import EvaluatorConfig, GraspEvaluator, save_evaluator

    config = EvaluatorConfig(points_per_cloud=64, pointnet_points=32, pointnet_widths=(8, 16), hand_points_per_shape=1, hidden_sizes=(16,))
    path.parent.mkdir(parents=True, exist_ok=True)
    save_evaluator(path, GraspEvaluator(config), config, {"train_object_ids": []})
    return path


@pytest.mark.slow
def test_an_evaluator_ranks_a_pool_of_model_samples_and_keeps_n_distinct(meshes, tmp_path, caplog):
    """--evaluator: evaluator.pool_factor x --n samples per object scored, the --n best distinct kept and refined, each
    with its score; the stores name the evaluator."""
    model, evaluator = _untrained_model(tmp_path / "cvae.pt"), _untrained_evaluator(tmp_path / "evaluator.pt")
    out = tmp_path / "ranked"
    config = {**TINY, "evaluator": {"pool_factor": 3}}
    with caplog.at_level(logging.INFO, logger="dexlite.grasp"):
        main(["grasp", str(meshes / "box.obj"), "--out", str(out), "--n", "4", "--renders", "0", "--threads", "1", "--model", str(model),
              "--evaluator", str(evaluator), "--resize-to-training", "--min-distinct", "0", "--config-json", json.dumps(config)])  # fmt: skip
    every = read_grasp_store(out / "all_grasps.zarr")
    assert len(every) == 4 and set(every.arrays["source"]) == {"model"}
    scores = np.asarray(every.arrays["evaluator_score"])
    assert scores.shape == (4,) and ((scores > 0) & (scores < 1)).all()
    assert every.attrs["evaluator"] == str(evaluator)
    assert "kept the 4 best-scored distinct of 12 samples" in caplog.text
    assert "ranked by a learned evaluator" in every.attrs["method"]


@pytest.mark.slow
def test_too_few_distinct_model_grasps_are_topped_up_by_optimization_from_scratch(grasp_run, meshes, tmp_path, capsys):
    """With --n 2 a model gives at most 2 distinct held grasps and a batch of optimization at most 2 more, fewer than
    --min-distinct 5: the top-up's first batch is made and tested exactly as --from-scratch makes it (grasp_run, same
    seed and threads); the second of --top-up-batches 2 runs, from another random stream, when the first added a
    distinct held grasp, and not when it added none (the unit test above covers both cases on made-up outcomes)."""
    model = _untrained_model(tmp_path / "cvae.pt")
    out = tmp_path / "topped_up"
    code = main(["grasp", str(meshes / "box.obj"), "--out", str(out), "--n", "2", "--renders", "1", "--threads", "2",
                 "--model", str(model), "--min-distinct", "5", "--top-up-batches", "2", "--config-json", json.dumps(TINY)])  # fmt: skip
    every, kept = read_grasp_store(out / "all_grasps.zarr"), read_grasp_store(out / "grasps.zarr")
    source = every.arrays["source"]
    held = np.asarray(every.arrays["lift_success"], bool)
    labels = np.asarray(every.arrays["distinct_label"])
    first_added = bool(set(labels[2:4][held[2:4]].tolist()) - set(labels[:2][held[:2]].tolist()))  # batch 1 added a distinct held grasp
    batches = 2 if first_added else 1
    assert source.tolist() == ["model"] * 2 + ["optimization"] * 2 * batches
    assert every.arrays["method"].tolist() == ["cvae_post"] * 2 + ["optimization"] * 2 * batches
    _, scratch = grasp_run
    alone = read_grasp_store(scratch / "all_grasps.zarr")
    box = alone.object_id == "user-box"
    optimized = source == "optimization"
    first, second = np.flatnonzero(optimized)[:2], np.flatnonzero(optimized)[2:]
    assert np.array_equal(every.hand_pose[first], alone.hand_pose[box])  # the --from-scratch path and seeds
    assert np.array_equal(every.arrays["lift_success"][first], alone.arrays["lift_success"][box])
    if batches == 2:
        assert not np.allclose(every.hand_pose[second], every.hand_pose[first])  # batch 2: other starts
    assert kept.arrays["source"].tolist() == source[np.sort(representatives_of(every))].tolist()  # each kept grasp's source
    assert every.attrs["topped_up"] == ["user-box"] and every.attrs["min_distinct"] == 5
    assert code == (0 if held.any() else 1)
    summary = (out / "summary.md").read_text()
    assert (f"< 5 (`--min-distinct`): optimization from scratch added {2 * batches} grasps in {batches} batch(es) of at most 2, "
            f"{int(held[optimized].sum())} held, "
            in summary.split("- `box.obj`: the model gave ")[1])  # fmt: skip
    assert f"| user-box | {int(held[~optimized].sum())}/2 (" in summary.split("## Model and optimization from scratch")[1]
    assert "topped up by energy optimization from scratch on 1 of 1 object(s)" in summary
    assert "optimization from scratch topped up the model's grasps of 1 object(s): user-box" in capsys.readouterr().out
    for picture in (out / "renders").glob("*.png"):
        assert picture.stat().st_size > 0


def representatives_of(grasps):
    """Rows of the kept grasps of a store: one per distinct label, as grasps.zarr keeps them."""
    from dexlite_pipeline.tools.grasp import representatives

    return representatives(grasps, np.asarray(grasps.arrays["distinct_label"]))


@pytest.mark.slow
def test_grasp_uses_the_shipped_model_when_no_model_is_given(meshes, tmp_path, monkeypatch):
    """Without --model (and without --from-scratch) the checkout's shipped model samples the grasps."""
    from dexlite_pipeline.model import shipped

    stand_in = _untrained_model(tmp_path / "models" / "cvae.pt")
    monkeypatch.setattr(shipped, "shipped_model_path", lambda hand="shadow": stand_in if hand == "shadow" else None)
    out = tmp_path / "shipped"
    main(["grasp", str(meshes / "box.obj"), "--out", str(out), "--n", "1", "--renders", "0", "--threads", "1", "--config-json", json.dumps(TINY)])
    every = read_grasp_store(out / "all_grasps.zarr")
    assert every.arrays["method"][every.arrays["source"] == "model"].tolist() == ["cvae_post"]
    assert f"model: {stand_in}" in (out / "summary.md").read_text()


@pytest.mark.slow
def test_the_object_frame_of_the_stores_is_the_real_object(grasp_run):
    """README 'Grasp store layout': the prepared mesh times the row's scale is the object in metres, and
    p / scale / normalization_factor + normalization_centre gives back the mesh file's coordinates."""
    from dexlite_pipeline.objects.assets import load_asset

    _, out = grasp_run
    every = read_grasp_store(out / "all_grasps.zarr")
    asset = load_asset(out / "objects", "user-box")
    scale = float(every.scale[every.object_id == "user-box"][0])
    vertices = np.asarray(asset.load_mesh().vertices) * scale
    assert np.allclose(np.ptp(vertices, axis=0), [0.08, 0.06, 0.10], atol=1e-4)
    in_file = vertices / scale / asset.meta["normalization_factor"] + np.asarray(asset.meta["normalization_centre"])
    assert np.allclose(in_file.min(axis=0), [-0.04, -0.03, -0.05], atol=1e-4) and np.allclose(in_file.max(axis=0), [0.04, 0.03, 0.05], atol=1e-4)


QUICK = ["--n", "1", "--renders", "0", "--threads", "1", "--from-scratch", "--config-json", json.dumps(TINY)]


@pytest.mark.slow
def test_units_mm_and_a_reused_out_folder(tmp_path, capsys):
    """A mesh in millimetres with --units mm is the same object as in metres; a second run into the same
    folder is refused, and --overwrite replaces the first run's output (no file of it is left)."""
    box = trimesh.creation.box((80.0, 60.0, 100.0))
    box.export(tmp_path / "box_mm.obj")
    out = tmp_path / "out"
    main(["grasp", str(tmp_path / "box_mm.obj"), "--out", str(out), "--units", "mm", *QUICK])
    every = read_grasp_store(out / "all_grasps.zarr")
    assert np.allclose(every.scale, 1.03 * np.linalg.norm([0.04, 0.03, 0.05]), rtol=1e-5)
    assert every.attrs["units"] == "mm" and "| user-box_mm | box_mm.obj | 6 x 8 x 10 cm |" in (out / "summary.md").read_text()
    assert "next: box_mm.obj: " in capsys.readouterr().out  # under 4 distinct held grasps from 1: the summary's hint, also printed
    stale = out / "renders" / "from_the_first_run.png"
    stale.parent.mkdir(exist_ok=True)
    stale.write_bytes(b"")
    capsys.readouterr()
    assert main(["grasp", str(tmp_path / "box_mm.obj"), "--out", str(out), "--units", "mm", *QUICK]) == 2
    error = capsys.readouterr().err.strip()
    assert error == f"dexlite grasp: error: --out {out}: holds an earlier run's output; pass --overwrite to replace it, or choose a new folder"
    assert stale.exists()
    quick_three = [*QUICK[:1], "3", *QUICK[2:]]
    main(["grasp", str(tmp_path / "box_mm.obj"), "--out", str(out), "--units", "mm", "--overwrite", "--no-distinct", *quick_three])
    assert not stale.exists() and (out / "summary.md").is_file()
    every, kept = read_grasp_store(out / "all_grasps.zarr"), read_grasp_store(out / "grasps.zarr")
    assert len(every) == 3 and kept.attrs["selection"] == "lift_success"  # --no-distinct: every held grasp, near-duplicates too
    assert len(kept) == int(np.asarray(every.arrays["lift_success"], bool).sum())
    assert "distinct only: no" in (out / "summary.md").read_text()


def _grasp_set(poses, held, six, passed, energy, object_ids=None, scale=0.1):
    from dexlite_pipeline.io.grasp_store import GraspSet

    n = len(poses)
    return GraspSet({
        "hand_pose": np.asarray(poses, np.float32), "object_id": np.asarray(object_ids or ["a"] * n, dtype=object),
        "scale": np.full(n, scale, np.float32), "lift_success": np.asarray(held, bool), "six_dir_success": np.asarray(six, bool),
        "six_dir_passed": np.asarray([[True] * k + [False] * (6 - k) for k in passed], bool), "E_total": np.asarray(energy, np.float32),
        "failure_reason": np.asarray(["" if h else "dropped" for h in held], dtype=object),
    })  # fmt: skip


def _pose(x, yaw_deg=0.0):
    pose = np.zeros(28)
    pose[0], pose[5] = x, np.deg2rad(yaw_deg)
    return pose


def test_grasps_stopped_as_hopeless_are_known_failures_named_by_their_optimizer():
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.tools.grasp.run import hopeless_optimizations

    base = {"hand_pose": np.zeros((3, 28), np.float32), "object_id": np.array(["a", "a", "b"], dtype=object), "scale": np.ones(3, np.float32),
            "stopped_at_iteration": np.array([0, 300, 600], np.int32)}
    assert hopeless_optimizations(GraspSet(dict(base))).tolist() == ["", *["optimization stopped early (hopeless)"] * 2]
    both = hopeless_optimizations(GraspSet({**base, "method": np.array(["cvae_post", "cvae_post", "optimization"], dtype=object)}))
    assert both.tolist() == ["", "post-optimization of the sample stopped early (hopeless)", "optimization stopped early (hopeless)"]
    assert hopeless_optimizations(GraspSet({k: v for k, v in base.items() if k != "stopped_at_iteration"})) is None


def test_distinct_grasps_keep_the_best_of_each_near_duplicate_group():
    """Palms within 2 cm and 30 degrees are one grasp; its best member (six-direction, directions passed, energy) is kept."""
    from dexlite_pipeline.settings import build_config
    from dexlite_pipeline.tools.grasp import distinct_labels, representatives

    poses = [_pose(0.0), _pose(0.01), _pose(0.015, 10), _pose(0.10), _pose(0.0, 90), _pose(0.005)]
    grasps = _grasp_set(poses, held=[1, 1, 1, 1, 1, 0], six=[0, 1, 0, 0, 0, 0], passed=[2, 6, 5, 1, 0, 6], energy=[0.1, 0.9, 0.5, 0.2, 0.3, 0.0])
    labels = distinct_labels(grasps, build_config({}))
    assert labels[5] == -1  # not held: no label
    assert labels[0] == labels[1] == labels[2] and len({labels[0], labels[3], labels[4]}) == 3
    kept = representatives(grasps, labels)
    assert sorted(kept.tolist()) == [1, 3, 4]  # grasp 1 passed the six-direction test: the best of its group
    assert kept[0] == 1
    # a stricter rule splits the group
    strict = distinct_labels(grasps, build_config({"diversity": {"distinct_translation_m": 0.004}}))
    assert len(set(strict[strict >= 0].tolist())) == 5


def test_distinct_grasps_of_other_objects_never_merge():
    from dexlite_pipeline.settings import build_config
    from dexlite_pipeline.tools.grasp import distinct_labels

    grasps = _grasp_set([_pose(0.0), _pose(0.0)], held=[1, 1], six=[0, 0], passed=[0, 0], energy=[0, 0], object_ids=["a", "b"])
    labels = distinct_labels(grasps, build_config({}))
    assert labels[0] != labels[1]


def _summary(rows, rejected=(), model="cvae.pt", kept=None, min_distinct=0, grasp_type="any"):
    from dexlite_pipeline.settings import build_config
    from dexlite_pipeline.tools.grasp import GraspRequest, MeshSize, summary_markdown

    config = build_config({})
    for r in rows:
        r.setdefault("size", MeshSize(0.13, (0.08, 0.1, 0.125)))
        r.setdefault("radii_m", [0.09])
        r.setdefault("six_dir", 0)
        r.setdefault("both", 0)
    request = GraspRequest(meshes=[], out_dir="out", grasps_per_object=32, model=model, min_distinct=min_distinct, grasp_type=grasp_type)
    held = sum(r["lift"] for r in rows)
    return summary_markdown(request, rows, list(rejected), "method", {"prepare": 1.0}, [], config.lift, config.diversity,
                            held if kept is None else kept)  # fmt: skip


def test_summary_counts_distinct_grasps_and_failure_reasons_with_a_hint_that_fits():
    rows = [{"object_id": "user-mug", "file": "mug.obj", "grasps": 32, "lift": 4, "distinct": 1,
             "failures": {"initial penetration": 20, "dropped": 8}}]  # fmt: skip
    text = _summary(rows, kept=1)
    assert "| user-mug | mug.obj | 8 x 10 x 12.5 cm | 32 | 4/32 (12%) | 1 |" in text
    assert "initial penetration 20, dropped 8" in text
    assert ("20 of the 28 failures start with the hand inside the object: try `--min-distinct 4` (optimization from scratch tops up "
            "the model's grasps and pushes the hand out of the object)") in text  # fmt: skip
    assert "`--min-distinct 0`: the model's grasps only; optimization from scratch never tops them up." in text
    assert "its 4 held grasps are near-duplicates of 1" in text
    assert "--units" not in text.split("## What to try next")[1].split("## Run")[0]  # the size was never in question
    assert "`dexgraspnet/` hold one of each distinct held grasp (the best): 1 grasp(s)" in text


def test_summary_says_per_source_what_the_model_and_the_top_up_gave():
    """A model run with the top-up: per object held and distinct of each source, why optimization ran or not, and
    no hint to run optimization where it already ran."""
    topped = {"object_id": "user-mug", "file": "mug.obj", "grasps": 64, "lift": 22, "distinct": 21, "failures": {"dropped": 42},
              "topped_up": True, "by_source": {"model": {"grasps": 32, "held": 3, "distinct": 2}, "optimization": {"grasps": 32, "held": 19, "distinct": 19}}}
    enough = {"object_id": "user-can", "file": "can.obj", "grasps": 32, "lift": 9, "distinct": 6, "failures": {"dropped": 23},
              "topped_up": False, "by_source": {"model": {"grasps": 32, "held": 9, "distinct": 6}}}
    few = {"object_id": "user-box", "file": "box.obj", "grasps": 64, "lift": 2, "distinct": 1, "failures": {"dropped": 62},
           "topped_up": True, "by_source": {"model": {"grasps": 32, "held": 0, "distinct": 0}, "optimization": {"grasps": 32, "held": 2, "distinct": 1}}}  # fmt: skip
    text = _summary([topped, enough, few], min_distinct=4)
    assert "| user-mug | 3/32 (9%) | 2 | 19/32 (59%) | 19 | 21 |" in text and "| user-can | 9/32 (28%) | 6 | not run | - | 6 |" in text
    assert ("- `mug.obj`: the model gave 2 distinct held grasp(s) < 4 (`--min-distinct`): optimization from scratch added 32 grasps in "
            "1 batch(es) of at most 4, 19 held, 19 distinct; 21 distinct held grasp(s) together.") in text  # fmt: skip
    assert "- `can.obj`: the model gave 6 distinct held grasp(s), at least 4 (`--min-distinct`): no optimization from scratch." in text
    hints = text.split("## What to try next")[1].split("## Run")[0]
    assert "`box.obj`: 1 distinct held grasp(s) of 64 from the model and optimization from scratch together" in hints
    assert "try more top-up batches (`--top-up-batches 8`) or more grasps (`--n 64`)." in hints
    assert "--min-distinct" not in hints and "mug.obj" not in hints
    assert "min distinct: 4 (`--min-distinct`)" in text
    assert "## Model and optimization from scratch" not in _summary([dict(enough)], model=None)  # --from-scratch: one source


def test_summary_counts_grasp_types_when_there_are_several_or_one_was_asked_for():
    from dexlite_pipeline.tools.grasp.summary import per_type_counts
    from dexlite_pipeline.settings import build_config

    grasps = _grasp_set([_pose(0.0), _pose(0.005), _pose(0.1), _pose(0.2)], held=[1, 1, 1, 0], six=[0] * 4, passed=[0] * 4, energy=[0] * 4,
                        object_ids=["a"] * 4)
    grasps.arrays["grasp_type"] = np.asarray(["pinch", "pinch", "tripod", "pinch"], dtype=object)
    by_type = per_type_counts(grasps, build_config({}))["a"]
    assert by_type == {"pinch": {"grasps": 3, "held": 2, "distinct": 1}, "tripod": {"grasps": 1, "held": 1, "distinct": 1}}
    row = {"object_id": "user-mug", "file": "mug.obj", "grasps": 4, "lift": 3, "distinct": 2, "failures": {"dropped": 1}, "by_type": by_type}
    text = _summary([row])
    assert "## Grasp types" in text and "Asked for any type (the model's training mix) (`--grasp-type any`)." in text
    assert "| user-mug | pinch | 3 | 2/3 (67%) | 1 |" in text and "| user-mug | tripod | 1 | 1/1 (100%) | 1 |" in text
    power = dict(row, by_type={"power": {"grasps": 4, "held": 3, "distinct": 2}})
    assert "## Grasp types" not in _summary([power])  # power grasps only, as the default asks: nothing to split
    assert "Asked for pinch grasps only (`--grasp-type pinch`)." in _summary([dict(row)], grasp_type="pinch")


def test_the_top_up_goes_to_the_objects_with_too_few_distinct_held_model_grasps():
    from types import SimpleNamespace

    from dexlite_pipeline.settings import build_config
    from dexlite_pipeline.tools.grasp import distinct_labels, objects_to_top_up

    # object a: two distinct held grasps (and a near-duplicate); b: four distinct; c: none held
    poses = [_pose(0.0), _pose(0.005), _pose(0.1), _pose(0.0), _pose(0.1), _pose(0.2), _pose(0.3), _pose(0.0)]
    objects = ["a", "a", "a", "b", "b", "b", "b", "c"]
    grasps = _grasp_set(poses, held=[1, 1, 1, 1, 1, 1, 1, 0], six=[0] * 8, passed=[0] * 8, energy=[0] * 8, object_ids=objects)
    labels = distinct_labels(grasps, build_config({}))
    assets = [SimpleNamespace(object_id=o) for o in "abc"]
    assert [a.object_id for a in objects_to_top_up(assets, grasps, labels, 4)] == ["a", "c"]
    assert [a.object_id for a in objects_to_top_up(assets, grasps, labels, 5)] == ["a", "b", "c"]
    assert [a.object_id for a in objects_to_top_up(assets, grasps, labels, 2)] == ["c"]
    assert objects_to_top_up(assets, grasps, labels, 0) == []  # --min-distinct 0: never


def test_the_top_up_adds_batches_until_each_object_has_enough_distinct_grasps_or_the_cap():
    """Object a reaches 4 distinct held grasps after one batch, b after three (the cap); c gains nothing from its first
    batch and d nothing from its second: neither gets another. Each batch goes to the objects still short and still
    gaining, with the batch number that seeds it."""
    from types import SimpleNamespace

    from dexlite_pipeline.settings import build_config
    from dexlite_pipeline.tools.grasp import top_up_until_distinct

    # per object, per batch: the palm offsets of the batch's held grasps (2 cm apart or more: distinct)
    held_offsets = {"a": [[0.1, 0.2, 0.3], [], []], "b": [[0.1], [0.2], [0.3]], "c": [[], [0.1], [0.2]], "d": [[0.1], [], [0.2]]}
    calls = []

    def optimized_batch(chosen, batch):
        calls.append((batch, [a.object_id for a in chosen]))
        poses, objects, held = [], [], []
        for asset in chosen:
            offsets = held_offsets[asset.object_id][batch]
            poses += [_pose(x) for x in offsets] + [_pose(0.5)]  # and one failed grasp
            objects += [asset.object_id] * (len(offsets) + 1)
            held += [1] * len(offsets) + [0]
        grasps = _grasp_set(poses, held=held, six=[0] * len(held), passed=[0] * len(held), energy=[0] * len(held), object_ids=objects)
        grasps.arrays["source"] = np.full(len(grasps), "optimization", dtype=object)
        return grasps

    model = _grasp_set([_pose(0.0)] * 4, held=[1, 1, 0, 1], six=[0] * 4, passed=[0] * 4, energy=[0] * 4, object_ids=["a", "b", "c", "d"])
    model.arrays["source"] = np.full(4, "model", dtype=object)
    assets = [SimpleNamespace(object_id=o) for o in "abcd"]
    tested, topped_up, short = top_up_until_distinct(assets, model, build_config({}), 4, 3, optimized_batch)
    assert calls == [(0, ["a", "b", "c", "d"]), (1, ["b", "d"]), (2, ["b"])]
    assert topped_up == ["a", "b", "c", "d"] and sorted(a.object_id for a in short) == ["c", "d"]
    assert len(tested) == 4 + (4 + 2 + 1 + 2) + (2 + 1) + 2  # model, then per batch: held grasps + one failure per object
    done, none_needed, _ = top_up_until_distinct(assets[:1], model.select(np.array([0])), build_config({}), 1, 3, optimized_batch)
    assert none_needed == [] and len(done) == 1  # enough already: no batch


def test_top_up_batches_after_the_first_have_their_own_random_streams():
    from dexlite_pipeline.tools.grasp import top_up_seed

    assert top_up_seed(7, 0) == 7  # the first batch: --from-scratch's seed
    seeds = [top_up_seed(s, b) for s in range(3) for b in range(1, 4)]
    assert len(set(seeds)) == len(seeds) and not set(seeds) & {0, 1, 2}
    assert top_up_seed(2, 3) == top_up_seed(2, 3)


def test_grasps_of_both_sources_join_with_each_ones_own_arrays_kept():
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.tools.grasp import concatenate_sources, grasp_rank

    model = _grasp_set([_pose(0.0)], held=[1], six=[0], passed=[3], energy=[0.5])
    model.arrays["E_post"] = model.arrays.pop("E_total")
    model.arrays["raw_hand_pose"] = np.ones((1, 28), np.float32)
    model.arrays["source"] = np.asarray(["model"], dtype=object)
    optimized = _grasp_set([_pose(0.1), _pose(0.2)], held=[1, 0], six=[0, 0], passed=[3, 6], energy=[0.2, 0.0])
    optimized.arrays["contact_index"] = np.zeros((2, 4), np.int64)
    optimized.arrays["source"] = np.asarray(["optimization"] * 2, dtype=object)
    both = concatenate_sources([model, optimized])
    assert isinstance(both, GraspSet) and len(both) == 3 and both.arrays["source"].tolist() == ["model", "optimization", "optimization"]
    assert np.isnan(both.arrays["raw_hand_pose"][1:]).all() and (both.arrays["raw_hand_pose"][0] == 1).all()
    assert (both.arrays["contact_index"][0] == -1).all() and np.isnan(both.arrays["E_total"][0]) and np.isnan(both.arrays["E_post"][1:]).all()
    assert grasp_rank(both).tolist() == [1, 0, 2]  # held first, then the lower energy of each row's own source


def test_summary_says_nothing_held_and_suggests_no_fix_when_there_is_none_to_make():
    nothing = _summary([{"object_id": "user-box", "file": "box.obj", "grasps": 8, "lift": 0, "distinct": 0, "failures": {"dropped": 8}}])
    assert "No grasp held: `grasps.zarr` is empty and no `dexgraspnet/` was written." in nothing
    assert "hold one of each" not in nothing and "the most common failure is 'dropped' (8 of 8)" in nothing
    fine = _summary([{"object_id": "user-box", "file": "box.obj", "grasps": 8, "lift": 8, "distinct": 5, "failures": {}}])
    assert "## What to try next" not in fine


def test_summary_names_the_meshes_the_hand_cannot_hold():
    rejected = [{"file": "/data/table.obj", "reason": "too large for the Shadow Hand: its thinnest side is 40 cm (the hand closes around at most 15 cm)",
                 "kind": "hand_fit"}]  # fmt: skip
    text = _summary([{"object_id": "user-box", "file": "box.obj", "grasps": 8, "lift": 8, "distinct": 5, "failures": {}}], rejected)
    assert "## Meshes not tried" in text and "`/data/table.obj`: too large for the Shadow Hand" in text
    assert "`table.obj` was not tried (too large for the Shadow Hand" in text and "give its unit with `--units`" in text


@pytest.fixture(scope="module")
def bad_inputs(tmp_path_factory):
    """Files for the table of bad inputs."""
    folder = tmp_path_factory.mktemp("bad")
    (folder / "empty").mkdir()
    (folder / "notes.txt").write_text("not a mesh")
    (folder / "garbage.obj").write_text("this is not a mesh\n")
    (folder / "garbage.pt").write_bytes(b"not a checkpoint")
    trimesh.creation.box((0.08, 0.06, 0.10)).export(folder / "box.obj")
    trimesh.creation.box((80.0, 60.0, 100.0)).export(folder / "box_in_mm.obj")
    trimesh.creation.box((0.003, 0.002, 0.004)).export(folder / "speck.obj")
    trimesh.creation.box((0.5, 0.4, 0.6)).export(folder / "crate.obj")
    trimesh.creation.box((0.02, 0.015, 0.01)).export(folder / "bead.obj")
    (folder / "used").mkdir()
    (folder / "used" / "summary.md").write_text("# Grasps\n")
    (folder / "mine").mkdir()
    (folder / "mine" / "thesis.tex").write_text("precious")
    (folder / "a_file").write_text("")
    inside = folder / "used_with_mesh"
    inside.mkdir()
    (inside / "summary.md").write_text("# Grasps\n")
    trimesh.creation.box((0.08, 0.06, 0.10)).export(inside / "box.obj")
    return folder


# (arguments with {d} for the bad-inputs folder, text the one error line must contain)
BAD_INPUTS = [
    (["{d}/missing.obj"], "{d}/missing.obj: no such file or folder"),
    (["{d}/notes.txt"], "{d}/notes.txt: not a mesh file (expected .obj or .stl)"),
    (["{d}/empty"], "{d}/empty: folder has no .obj/.stl files"),
    (["{d}/garbage.obj"], "garbage.obj: unreadable"),
    (["{d}/box_in_mm.obj"], "box_in_mm.obj: largest extent 100 m, implausible for a hand-held object (1 cm to 1 m); likely in mm (--units mm: 10 cm)"),
    (["{d}/box.obj", "--units", "mm"], "box.obj: largest extent 0.1 mm (0.0001 m), implausible for a hand-held object"),
    (["{d}/speck.obj"], "speck.obj: largest extent 0.004 m, implausible for a hand-held object (1 cm to 1 m); no unit makes it a hand-held object"),
    (["{d}/crate.obj"], "crate.obj: too large for the Shadow Hand: its thinnest side is 40 cm"),
    (["{d}/bead.obj"], "bead.obj: too small for the Shadow Hand: 2 cm at most"),
    (["{d}/box.obj", "--units", "km"], "argument --units: invalid choice: 'km'"),
    (["{d}/box.obj", "--n", "0"], "--n must be at least 1, got 0"),
    (["{d}/box.obj", "--n", "-4"], "--n must be at least 1, got -4"),
    (["{d}/box.obj", "--n", "many"], "argument --n: invalid int value: 'many'"),
    (["{d}/box.obj", "--renders", "-1"], "--renders must be 0 or more, got -1"),
    (["{d}/box.obj", "--threads", "-2"], "--threads must be at least 1, got -2"),
    (["{d}/box.obj", "--device", "gpu"], "--device gpu: not a device (expected auto, cpu, cuda or cuda:N)"),
    (["{d}/box.obj", "--device", "cuda:x"], "--device cuda:x: not a device"),
    (["{d}/box.obj", "--config-json", '{"device": "tpu"}'], "device: 'tpu' does not match"),
    (["{d}/box.obj", "--model", "{d}/missing.pt"], "--model {d}/missing.pt: no such file"),
    (["{d}/box.obj", "--model", "{d}/garbage.pt"], "--model {d}/garbage.pt: not a readable model file"),
    (["{d}/box.obj", "--model", "{d}/garbage.pt", "--from-scratch"], "--model and --from-scratch exclude each other"),
    (["{d}/box.obj", "--units", "cm", "--resize-to-training"], "--units and --resize-to-training exclude each other"),
    (["{d}/box.obj", "--evaluator", "{d}/missing.pt"], "--evaluator {d}/missing.pt: no such file"),
    (["{d}/box.obj", "--evaluator", "{d}/garbage.pt"], "--evaluator {d}/garbage.pt: not a readable grasp evaluator file"),
    (["{d}/box.obj", "--evaluator", "{d}/garbage.pt", "--no-evaluator"], "--evaluator and --no-evaluator exclude each other"),
    (["{d}/box.obj", "--evaluator", "{d}/garbage.pt", "--from-scratch"], "--evaluator and --from-scratch exclude each other"),
    (["{d}/box.obj", "--min-distinct", "-1"], "--min-distinct must be 0 or more, got -1"),
    (["{d}/box.obj", "--min-distinct", "few"], "argument --min-distinct: invalid int value: 'few'"),
    (["{d}/box.obj", "--from-scratch", "--min-distinct", "4"], "--min-distinct and --from-scratch exclude each other"),
    (["{d}/box.obj", "--from-scratch", "--min-distinct", "0"], "--min-distinct and --from-scratch exclude each other"),
    (["{d}/box.obj", "--top-up-batches", "0"], "--top-up-batches must be at least 1, got 0"),
    (["{d}/box.obj", "--from-scratch", "--top-up-batches", "2"], "--top-up-batches and --from-scratch exclude each other"),
    (["{d}/box.obj", "--config-json", '{"lift": {"friction": "high"}}'], 'lift.friction: expected a number, got a string "high"'),
    (["{d}/box.obj", "--config-json", '{"lift": {"frictoin": 1.0}}'], "frictoin"),
    (["{d}/box.obj", "--config-json", "{not json"], "--config-json"),
    (["{d}/box.obj", "--out", "{d}/used"], "--out {d}/used: holds an earlier run's output; pass --overwrite to replace it"),
    (["{d}/box.obj", "--out", "{d}/mine", "--overwrite"], "--out {d}/mine: folder is not empty and holds no earlier dexlite grasp output"),
    (["{d}/box.obj", "--out", "{d}/a_file"], "--out {d}/a_file: exists and is not a folder"),
    (["{d}/used_with_mesh/box.obj", "--out", "{d}/used_with_mesh", "--overwrite"], "--overwrite would delete the input mesh"),
    (["--out", "{d}/new"], "the following arguments are required: meshes"),
    (["{d}/box.obj", "--no-such-flag"], "unrecognized arguments: --no-such-flag"),
]
if not __import__("torch").cuda.is_available():
    BAD_INPUTS.append((["{d}/box.obj", "--device", "cuda"], "--device cuda: CUDA is not available on this machine; use --device cpu"))
    BAD_INPUTS.append((["{d}/box.obj", "--config-json", '{"device": "cuda"}'], "config device cuda: CUDA is not available"))


@pytest.mark.parametrize("arguments, expected", BAD_INPUTS, ids=[" ".join(a).replace("{d}/", "") for a, _ in BAD_INPUTS])
def test_every_bad_input_is_one_line_with_exit_status_2_before_any_work(bad_inputs, arguments, expected, capsys, caplog):
    d = str(bad_inputs)
    args = [a.replace("{d}", d) for a in arguments]
    if "--out" not in args:
        args += ["--out", f"{d}/new"]
    before = sorted(p.relative_to(bad_inputs) for p in bad_inputs.rglob("*"))
    with caplog.at_level(logging.INFO):
        try:
            code = main(["grasp", *args])
        except SystemExit as exc:  # argparse's own errors
            code = exc.code
    error = capsys.readouterr().err
    assert code == 2
    assert len(error.strip().splitlines()) == 1 and error.startswith("dexlite grasp: error: ") and "Traceback" not in error
    assert expected.replace("{d}", d) in error
    assert sorted(p.relative_to(bad_inputs) for p in bad_inputs.rglob("*")) == before  # nothing prepared or written
    assert not [r for r in caplog.records if r.name.startswith("dexlite") and r.levelno >= logging.INFO]  # no work started


def test_a_mesh_rejected_in_preparation_is_reported_once_and_never_as_prepared(tmp_path, capsys, caplog):
    flat = tmp_path / "flat.obj"
    flat.write_text("v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0.1 0.1 0\nf 1 2 3\nf 2 4 3\n")
    with caplog.at_level(logging.INFO):
        assert main(["grasp", str(flat), "--out", str(tmp_path / "out"), "--threads", "1", "--from-scratch", "--config-json", json.dumps(TINY)]) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith("dexlite grasp: error: none of the 1 mesh(es) could be used:") and "flat.obj: degenerate: flat" in error
    assert len(error.splitlines()) == 1
    messages = [r.getMessage() for r in caplog.records]
    assert not [m for m in messages if "degenerate" in m]  # the reason appears once: in the error line
    assert not [m for m in messages if "prepared" in m and "could be used" not in m]


@pytest.mark.slow
def test_on_a_table_no_held_grasp_reaches_below_it(grasp_run):
    """Tabletop mode (the default): every grasp records its object's table, and no held grasp has a hand point below it."""
    from dexlite_pipeline.energy.table_clearance import grasp_table_depths
    from dexlite_pipeline.tabletop import TABLE_TOLERANCE_M, planes_from_store

    _, out = grasp_run
    every = read_grasp_store(out / "all_grasps.zarr")
    planes = planes_from_store(every)
    assert planes is not None and {"user-box", "user-cup"} <= set(planes.planes)
    depth = grasp_table_depths(every, planes)
    held = np.asarray(every.arrays["lift_success"], bool)
    assert np.isfinite(depth).all() and (depth[held] <= TABLE_TOLERANCE_M).all()
    in_table = np.asarray(every.arrays["failure_reason"], dtype=object) == "hand_in_table"
    assert (depth[in_table] > TABLE_TOLERANCE_M).all()
