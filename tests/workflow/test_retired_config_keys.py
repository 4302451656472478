"""A config with a renamed or removed key (``config.RETIRED_KEYS``) stops the workflow before any job is planned,
with one line naming the key and its replacement instead of the schema's bare unknown-key error."""

from __future__ import annotations

import subprocess

import pytest
from workflow_harness import snakemake_command, snakemake_env, tiny_config, write_config

from dexlite_pipeline.config import merge_config


@pytest.mark.parametrize(
    "old, hint",
    [
        ("seed_grasps", "config key seed_grasps was renamed optimize_grasps ("),
        ("energy.object_points", "config key energy.object_points was renamed energy.object_point_spacing_m (a count of E_pen's object points "
                                 "per object became their mean spacing in metres"),
    ],
)  # fmt: skip
def test_a_dry_run_with_an_old_key_fails_naming_its_replacement(tmp_path, old, hint):
    config = tiny_config(tmp_path / "meshes")
    if old == "seed_grasps":
        config["seed_grasps"] = config.pop("optimize_grasps")  # a config written before the rename
    else:
        config = merge_config(config, {"energy": {"object_points": 2000}})
    write_config(tmp_path / "run", config)

    done = subprocess.run(
        snakemake_command(tmp_path / "run", "--dry-run", "--cores", "1"), env=snakemake_env(), capture_output=True, text=True, timeout=300
    )

    output = done.stdout + done.stderr
    assert done.returncode != 0, output[-3000:]
    assert "WorkflowError" in output and hint in output, output[-3000:]
    assert "Job stats" not in output  # nothing was planned
