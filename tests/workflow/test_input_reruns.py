"""Files that stages read from outside results/ are their inputs: the user's mesh folders
(prepare_objects) and a DexGraspNet download (import_dexgraspnet).

Dry runs of a fresh directory check which files each stage lists; one real run of just
those two stages, on meshes and a DexGraspNet copy kept inside the run's directory
(relative paths in the config, so each test changes its own copy), checks what reruns.
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import pytest
from workflow_harness import (
    grasp_fixture,
    job_blocks,
    local_run_args,
    planned_rules,
    run_snakemake,
    tiny_config,
    write_config,
    write_tiny_meshes,
)

from dexlite_pipeline.objects.sources import folder_sources

TARGETS = ("results/objects/catalog.parquet", "results/dexgraspnet/grasps.zarr")


@pytest.fixture()
def dexgraspnet_copy(tmp_path) -> Path:
    return Path(shutil.copytree(grasp_fixture(), tmp_path / "dexgraspnet"))


def planned_inputs(workdir: Path, rule: str) -> list[str]:
    """The input files of ``rule``'s job in a dry run of ``workdir``."""
    output = run_snakemake(workdir, "--dry-run", "--cores", "2", "all")
    block = next(block for block in job_blocks(output) if block["rule"] == rule)
    return block["input"].split(", ") if block.get("input") else []


def test_object_preparation_lists_the_mesh_files_the_loader_reads(tmp_path):
    meshes, heldout = tmp_path / "meshes", tmp_path / "heldout"
    (meshes / "nested").mkdir(parents=True)
    heldout.mkdir()
    for path in ("meshes/box.obj", "meshes/cylinder.STL", "meshes/notes.txt", "meshes/nested/inner.obj", "heldout/mug.Obj"):
        (tmp_path / path).write_text("not read by a dry run\n")
    write_config(tmp_path / "run", tiny_config(meshes, objects={"heldout_mesh_dirs": [str(heldout)]}, dexgraspnet={"root": ""}))

    inputs = planned_inputs(tmp_path / "run", "prepare_objects")

    loader = [s.file for s in folder_sources([meshes], heldout=False) + folder_sources([heldout], heldout=True)]
    benchmark_split = [p for p in inputs if Path(p).name == "benchmark_split.yaml"]
    assert len(benchmark_split) == 1  # the benchmark split the stage reads (objects.benchmark_heldout)
    assert sorted(p for p in inputs if p not in benchmark_split) == sorted(loader)
    assert {Path(p).name for p in inputs} == {"box.obj", "cylinder.STL", "mug.Obj", "benchmark_split.yaml"}


def test_dexgraspnet_import_lists_the_grasp_files_and_their_meshes(tmp_path, dexgraspnet_copy):
    grasp_files = sorted((dexgraspnet_copy / "dataset").glob("*.npy"))
    without_mesh = dexgraspnet_copy / "dataset" / "core-new-object.npy"
    shutil.copy2(grasp_files[0], without_mesh)
    (tmp_path / "meshes").mkdir()
    write_config(tmp_path / "run", tiny_config(tmp_path / "meshes", dexgraspnet={"root": str(dexgraspnet_copy)}))

    inputs = planned_inputs(tmp_path / "run", "import_dexgraspnet")

    meshes_of_files = [dexgraspnet_copy / "meshdata" / p.stem / "coacd" / "decomposed.obj" for p in grasp_files]
    assert sorted(inputs) == sorted(map(str, [*grasp_files, without_mesh, *meshes_of_files]))


@pytest.fixture(scope="module")
def inputs_run(tmp_path_factory) -> Path:
    """A directory where prepare_objects and import_dexgraspnet ran on ./meshes and ./dexgraspnet."""
    workdir = tmp_path_factory.mktemp("inputs_run")
    write_tiny_meshes(workdir / "meshes")
    shutil.copytree(grasp_fixture(), workdir / "dexgraspnet")
    write_config(workdir, tiny_config(Path("meshes"), dexgraspnet={"root": "dexgraspnet"}))
    run_snakemake(workdir, *local_run_args(), *TARGETS)
    return workdir


@pytest.fixture()
def run_copy(inputs_run, tmp_path) -> Path:
    """A copy of the run (outputs, metadata, inputs, mtimes) that a test may change."""
    return Path(shutil.copytree(inputs_run, tmp_path / "run", symlinks=True))


def planned(workdir: Path) -> set[str]:
    return planned_rules(workdir, *TARGETS)


def edit(path: Path) -> None:
    """Change the content of ``path`` and give it a modification time after every output.

    (Snakemake ignores a newer input whose content it recorded as unchanged.)
    """
    with open(path, "ab") as file:
        file.write(b"\n# edited\n")
    later = time.time() + 60
    os.utime(path, (later, later))


@pytest.mark.slow
def test_unchanged_inputs_plan_nothing(inputs_run):
    assert planned(inputs_run) == set()


@pytest.mark.slow
def test_new_mesh_file_reruns_object_preparation(run_copy):
    shutil.copy2(run_copy / "meshes" / "box.obj", run_copy / "meshes" / "second_box.STL")

    assert planned(run_copy) == {"prepare_objects"}


@pytest.mark.slow
def test_edited_mesh_file_reruns_object_preparation(run_copy):
    edit(run_copy / "meshes" / "sphere.obj")

    assert planned(run_copy) == {"prepare_objects"}


@pytest.mark.slow
def test_other_files_in_a_mesh_folder_rerun_nothing(run_copy):
    (run_copy / "meshes" / "notes.txt").write_text("not a mesh\n")
    (run_copy / "meshes" / "old").mkdir()
    shutil.copy2(run_copy / "meshes" / "box.obj", run_copy / "meshes" / "old" / "box.obj")

    assert planned(run_copy) == set()


def _add_grasp_file(root: Path) -> None:
    """A new object in the download: a copy of the first grasp file and its mesh under a new code."""
    source = sorted((root / "dataset").glob("*.npy"))[0]
    shutil.copy2(source, root / "dataset" / "core-added-object.npy")
    shutil.copytree(root / "meshdata" / source.stem, root / "meshdata" / "core-added-object")


def _edit_grasp_file(root: Path) -> None:
    edit(sorted((root / "dataset").glob("*.npy"))[0])


def _edit_mesh(root: Path) -> None:
    edit(sorted((root / "meshdata").glob("*/coacd/decomposed.obj"))[0])


@pytest.mark.slow
@pytest.mark.parametrize("change", [_add_grasp_file, _edit_grasp_file, _edit_mesh], ids=lambda f: f.__name__.strip("_"))
def test_dexgraspnet_file_change_reruns_the_import(run_copy, change):
    change(run_copy / "dexgraspnet")

    assert planned(run_copy) == {"import_dexgraspnet"}
