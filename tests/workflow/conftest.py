"""One complete run of the workflow on the tiny config, shared by the workflow tests."""

from __future__ import annotations

import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import pytest
from workflow_harness import (
    freeze_checkout,
    local_run_args,
    rule_graph,
    run_snakemake,
    tiny_config,
    write_config,
    write_tiny_meshes,
)


@dataclass(frozen=True)
class CompletedRun:
    workdir: Path
    config: dict
    graph: dict[str, set[str]]
    seconds: float


@pytest.fixture(scope="session", autouse=True)
def frozen_checkout(tmp_path_factory) -> Path:
    """The repository as it is when the session starts; every workflow run uses this copy."""
    return freeze_checkout(tmp_path_factory.mktemp("checkout"))


@pytest.fixture(scope="session")
def complete_run(frozen_checkout, tmp_path_factory) -> CompletedRun:
    """The tiny config run to the end with `--cores 2` (read-only for tests: copy it to change it)."""
    workdir = tmp_path_factory.mktemp("complete_run")
    config = tiny_config(write_tiny_meshes(tmp_path_factory.mktemp("tiny_meshes")))
    write_config(workdir, config)
    start = time.monotonic()
    # ~60 jobs with the data loop's two rounds: ~5 CPU-minutes, far longer on a shared machine (the guard is against a hang)
    run_snakemake(workdir, *local_run_args(), "all", timeout_s=1800)
    seconds = time.monotonic() - start
    return CompletedRun(workdir=workdir, config=config, graph=rule_graph(workdir), seconds=seconds)


@pytest.fixture()
def scratch_copy(complete_run, tmp_path) -> Path:
    """A copy of the complete run (outputs, metadata, mtimes) that a test may change."""
    workdir = tmp_path / "run"
    shutil.copytree(complete_run.workdir, workdir, symlinks=True)
    return workdir
