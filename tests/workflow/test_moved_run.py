"""A finished run whose folder is moved or copied plans nothing.

Users run `snakemake` in the checkout, so every file the rules read from the checkout (the
benchmark and household splits, the shipped model, the learning curve) must be named relative to
the run's folder: Snakemake records each job's input paths and replans a job whose set of inputs
changed, so an absolute path would rerun the whole workflow from object preparation after a
rename, a copy to a cluster filesystem or another machine.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from workflow_harness import CHECKOUT_PARTS, GRASP_FIXTURE_PART, checkout, job_blocks, local_run_args, planned_rules, run_snakemake, tiny_config, write_config, write_tiny_meshes

TARGET = "results/objects/catalog.parquet"
CHECKOUT_FILES = ("docs/learning_curve.csv",)  # besides the parts every test run copies: the report reads it


def checkout_copy(destination: Path) -> Path:
    """A copy of the frozen checkout with the tiny config and meshes inside it: a user's run folder."""
    for part in (*CHECKOUT_PARTS, *CHECKOUT_FILES):
        source = checkout() / part
        if source.is_dir():
            shutil.copytree(source, destination / part, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        elif source.is_file():
            (destination / part).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, destination / part)
    write_tiny_meshes(destination / "meshes")
    write_config(destination, tiny_config(Path("meshes"), dexgraspnet={"root": GRASP_FIXTURE_PART}))
    return destination


def test_no_job_names_an_absolute_path_in_the_run_folder(tmp_path):
    workdir = checkout_copy(tmp_path / "dexlite")

    output = run_snakemake(workdir, "--dry-run", "--cores", "2", "all")

    inputs = [path for block in job_blocks(output) if block.get("input") for path in block["input"].split(", ")]
    assert any(Path(p).name == "benchmark_split.yaml" for p in inputs)
    absolute = sorted({p for p in inputs if Path(p).is_absolute() and Path(p).is_relative_to(workdir)})
    assert absolute == [], f"inputs named by an absolute path (a moved run would replan their jobs): {absolute[:5]}"


@pytest.mark.slow
def test_a_moved_run_plans_nothing(tmp_path):
    original = checkout_copy(tmp_path / "dexlite")
    run_snakemake(original, *local_run_args(), TARGET)
    assert planned_rules(original, TARGET) == set()

    moved = tmp_path / "elsewhere" / "renamed"
    shutil.copytree(original, moved, symlinks=True)  # outputs, Snakemake's records and mtimes
    shutil.rmtree(original)

    assert planned_rules(moved, TARGET) == set()
