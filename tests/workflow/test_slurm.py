"""Sharded run through a real SLURM: the tiny config via `--executor slurm` equals a local run.

The test starts its own one-node cluster (munged, slurmctld, slurmd on loopback; see
slurm_cluster.py), runs the workflow with the repository's SLURM profile, sized for that
node (threads, memory and wall time capped; partition set), and compares every output with
the shared local run of the same config. It skips, saying why, where SLURM cannot run.
"""

from __future__ import annotations

import re
import time

import pytest
import yaml
import yte
from outputs import results_differences
from slurm_cluster import ClusterUnavailable, local_slurm_cluster, missing_requirements
from workflow_harness import TEST_THREADS, checkout, job_blocks, run_snakemake, write_config

pytestmark = [pytest.mark.slurm, pytest.mark.slow]

JOB_MEMORY_MB = 1000
JOB_RUNTIME_MIN = 15


def node_sized_profile(cluster) -> dict:
    """profiles/slurm/config.yaml with every rule's resources capped to the test node."""
    with open(checkout() / "profiles" / "slurm" / "config.yaml") as stream:
        profile = yte.process_yaml(stream, require_use_yte=True)
    assert profile["executor"] == "slurm"
    profile["set-threads"] = {rule: TEST_THREADS for rule in profile["set-threads"]}
    profile["set-resources"] = {
        rule: {**resources, "mem_mb": JOB_MEMORY_MB, "runtime": JOB_RUNTIME_MIN}
        for rule, resources in profile["set-resources"].items()
    }
    profile["default-resources"] = {
        **profile.get("default-resources", {}),
        "mem_mb": JOB_MEMORY_MB,
        "runtime": JOB_RUNTIME_MIN,
        "slurm_partition": cluster.partition,
    }
    profile.update(
        {
            "slurm-status-command": "squeue",  # no accounting database on the test node
            "slurm-init-seconds-before-status-checks": 1,
            "slurm-no-account": True,
            "latency-wait": 5,
            "retries": 0,
            "slurm-logdir": "logs/slurm",
            "slurm-keep-successful-logs": True,
        }
    )
    return profile


def test_slurm_run_equals_local_run(complete_run, tmp_path):
    reason = missing_requirements()
    if reason:
        pytest.skip(f"local SLURM not available: {reason}")
    workdir = tmp_path / "slurm_run"
    write_config(workdir, complete_run.config)
    try:
        with local_slurm_cluster(tmp_path / "cluster") as cluster:
            profile_dir = tmp_path / "profile"
            profile_dir.mkdir()
            (profile_dir / "config.yaml").write_text(yaml.safe_dump(node_sized_profile(cluster)))
            start = time.monotonic()
            output = run_snakemake(workdir, "--profile", str(profile_dir), "all", env=cluster.env, timeout_s=900)
            seconds = time.monotonic() - start
            submitted = cluster.run("squeue", "--states=all", "--noheader", "--format=%j|%T")
    except ClusterUnavailable as exc:
        pytest.skip(f"local SLURM did not start: {exc}")

    jobs = job_blocks(output)
    remote = [b for b in jobs if b["local"] == "no"]
    submissions = re.findall(r"has been submitted with SLURM jobid (\d+)", output)
    states = [line.split("|")[1] for line in submitted.split() if "|" in line]
    assert {b["rule"] for b in jobs} == set(complete_run.graph), "the SLURM run did not run every rule"
    assert remote and len(submissions) == len(remote) == len(states), (len(submissions), len(remote), states)
    assert set(states) == {"COMPLETED"}, states
    assert results_differences(complete_run.workdir / "results", workdir / "results") == {}, output[-3000:]
    print(f"SLURM run of the tiny config: {seconds:.0f} s (local: {complete_run.seconds:.0f} s)")
