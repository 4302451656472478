"""Resumable, never corrupt: SIGKILL a run in the middle of a sharded stage, start it again.

The restarted run completes; the shard that had finished before the kill is not computed
again (same mtime, same log); the shard whose job was killed leaves no output that could
pass for finished (atomic writes), and the final results equal those of the uninterrupted
run of the same config.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest
from outputs import results_differences
from workflow_harness import (
    job_blocks,
    local_run_args,
    planned_rules,
    run_snakemake,
    snakemake_command,
    snakemake_env,
    wildcard,
)

pytestmark = pytest.mark.slow

# The sharded stage killed mid-run: late in the DAG, so the test redoes little.
KILLED_STAGE = "post_optimize"
KILL_TIMEOUT_S = 300


def _stage_files(workdir: Path, stage: str) -> tuple[dict[str, Path], dict[str, Path]]:
    """First output and log of each shard job of ``stage``, by shard id (from a dry run that forces it)."""
    output = run_snakemake(workdir, "--dry-run", "--forcerun", stage, "--cores", "1")
    blocks = [b for b in job_blocks(output) if b["rule"] == stage and wildcard(b, "shard") is not None]
    first = lambda field: {wildcard(b, "shard"): workdir / b[field].split(",")[0].strip() for b in blocks}  # noqa: E731
    return first("output"), first("log")


def _written_since(path: Path, since: float) -> bool:
    return path.exists() and path.stat().st_mtime >= since


def _shards_started(output: str, stage: str) -> list[str]:
    return [wildcard(b, "shard") for b in job_blocks(output) if b["rule"] == stage]


def _wait_for(condition, what: str, process: subprocess.Popen, log: Path) -> None:
    deadline = time.monotonic() + KILL_TIMEOUT_S
    while time.monotonic() < deadline:
        if condition():
            return
        if process.poll() is not None:
            raise AssertionError(f"snakemake ended before {what}:\n{log.read_text()[-4000:]}")
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}:\n{log.read_text()[-4000:]}")


def test_killed_run_resumes_without_recomputing_finished_shards(complete_run, tmp_path):
    stage = KILLED_STAGE
    workdir = tmp_path / "run"
    shutil.copytree(complete_run.workdir, workdir, symlinks=True)
    shard_outputs, shard_logs = _stage_files(workdir, stage)
    assert len(shard_outputs) >= 2, f"{stage}: the tiny config must give at least two shards"

    # One core: shards run one after the other, so one finishes while the next one runs.
    log = tmp_path / "killed_run.log"
    with open(log, "w") as out:
        process = subprocess.Popen(
            snakemake_command(workdir, "--forcerun", stage, *local_run_args(cores=1), "all"),
            env=snakemake_env(), stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
        )
    try:
        started = time.time()
        # Watch the files, not Snakemake's (buffered) log: an output appears at once, by rename.
        _wait_for(lambda: any(_written_since(p, started) for p in shard_outputs.values()), f"the first {stage} shard", process, log)
        finished = [s for s, p in shard_outputs.items() if _written_since(p, started)]
        assert len(finished) == 1, f"expected one freshly finished shard, found {finished}"
        # Let the next shard's job get going (its log file is opened when it starts), then kill
        # snakemake and its jobs at once.
        _wait_for(lambda: any(_written_since(shard_logs[s], started) for s in shard_outputs if s not in finished),
                  f"the second {stage} shard to start", process, log)
        time.sleep(1.0)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
        process.wait(timeout=30)
    assert process.returncode == -signal.SIGKILL, "the run ended before it could be killed"
    finished_shard = finished[0]
    finished_mtime = shard_outputs[finished_shard].stat().st_mtime_ns
    unfinished = {s: p for s, p in shard_outputs.items() if s != finished_shard}
    for path in unfinished.values():
        assert not path.exists() or path.stat().st_mtime < started, f"{path} was written by a killed job"

    # What a job killed while writing leaves: a temporary sibling (planted here too, so the
    # check does not depend on when the kill landed). It must never count as the output.
    unfinished_path = sorted(unfinished.values())[0]
    planted = unfinished_path.with_name(f".{unfinished_path.name}.tmp-0000dead")
    planted.mkdir(parents=True, exist_ok=True)
    (planted / "zarr.json").write_text("{}")

    run_snakemake(workdir, "--unlock")
    resumed = run_snakemake(workdir, *local_run_args(), "--rerun-incomplete", "all")

    assert finished_shard not in _shards_started(resumed, stage), f"finished shard {finished_shard} was recomputed"
    assert shard_outputs[finished_shard].stat().st_mtime_ns == finished_mtime
    for shard, path in unfinished.items():
        assert path.exists() and path.stat().st_mtime >= started, f"shard {shard} was not redone"
    leftovers = sorted(str(p) for p in (workdir / "results").rglob("*.tmp-*"))
    assert not leftovers, f"temporary outputs left behind: {leftovers}"
    assert planned_rules(workdir) == set()
    assert results_differences(complete_run.workdir / "results", workdir / "results") == {}
