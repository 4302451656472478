"""Static contracts of the workflow files: rules, profiles and the conda environment agree.

Fast checks that need no Snakemake run: every rule logs, benchmarks, declares the conda
env and hashes its code; every rule has threads and resources in the SLURM profile and
threads in the local profile; the GPU option reaches train_cvae only; the conda env lists
exactly the package's dependencies and the same CPU torch as install.sh.
"""

from __future__ import annotations

import io
import re

import pytest
import yaml
import yte
from workflow_harness import REPO, rule_blocks

RULE_FILES = sorted((REPO / "workflow" / "rules").glob("*.smk"))


def slurm_profile(env: dict[str, str] | None = None, monkeypatch=None) -> dict:
    for key, value in (env or {}).items():
        monkeypatch.setenv(key, value)
    text = (REPO / "profiles" / "slurm" / "config.yaml").read_text()
    return yte.process_yaml(io.StringIO(text), require_use_yte=True)


def test_every_rule_logs_benchmarks_hashes_code_and_declares_the_env():
    blocks = rule_blocks()
    assert "prepare_objects" in blocks
    for rule, body in blocks.items():
        for directive in ("log:", "benchmark:", "conda:", "params:"):
            assert re.search(rf"^\s+{directive}", body, re.M), f"rule {rule} has no {directive}"
        assert "code_hash(" in body, f"rule {rule}: params must include code=code_hash(...)"
        assert "{LOGS}" in body.split("log:")[1], f"rule {rule}: log outside {{LOGS}}"
        assert not re.search(r"^\s+resources:", body, re.M), f"rule {rule}: resources belong in profiles/"


def test_profiles_size_every_rule(monkeypatch):
    rules = set(rule_blocks())
    profile = slurm_profile(monkeypatch=monkeypatch)
    local = yaml.safe_load((REPO / "profiles" / "local" / "config.yaml").read_text())
    assert rules <= set(profile["set-threads"]), f"SLURM profile lacks threads for {rules - set(profile['set-threads'])}"
    assert rules <= set(profile["set-resources"]), f"SLURM profile lacks resources for {rules - set(profile['set-resources'])}"
    assert rules <= set(local["set-threads"]), f"local profile lacks threads for {rules - set(local['set-threads'])}"
    for rule, resources in profile["set-resources"].items():
        assert resources["mem_mb"] > 0 and resources["runtime"] > 0, rule
    assert profile["executor"] == "slurm"


def test_slurm_profile_site_settings_and_gpu_option(monkeypatch):
    default = slurm_profile(monkeypatch=monkeypatch)
    assert "gpu" not in default["set-resources"]["train_cvae"]
    assert "slurm_partition" not in default["default-resources"]
    assert default["slurm-no-account"] is True

    site = slurm_profile(
        {"DEXLITE_SLURM_PARTITION": "cpu", "DEXLITE_SLURM_ACCOUNT": "lab42", "DEXLITE_TRAIN_GPUS": "2",
         "DEXLITE_GPU_PARTITION": "gpu"},
        monkeypatch,
    )
    assert site["default-resources"]["slurm_partition"] == "cpu"
    assert site["default-resources"]["slurm_account"] == "lab42"
    assert site["slurm-no-account"] is False
    assert site["set-resources"]["train_cvae"]["gpu"] == 2
    assert site["set-resources"]["train_cvae"]["slurm_partition"] == "gpu"
    others = {r: res for r, res in site["set-resources"].items() if r != "train_cvae"}
    assert not any("gpu" in res for res in others.values())


class _UniqueKeyLoader(yaml.SafeLoader):
    """A YAML loader that refuses a key given twice in one mapping (YAML keeps the last silently)."""

    def construct_mapping(self, node, deep=False):
        keys = [self.construct_object(key, deep=deep) for key, _ in node.value]
        repeated = sorted({k for k in keys if keys.count(k) > 1})
        if repeated:
            raise yaml.constructor.ConstructorError(None, None, f"repeated keys {repeated}", node.start_mark)
        return super().construct_mapping(node, deep=deep)


def test_profiles_and_env_have_no_repeated_keys():
    for path in [*(REPO / "profiles").glob("*/config.yaml"), REPO / "envs" / "dexlite.yaml", REPO / "config.yaml"]:
        yaml.load(path.read_text(), Loader=_UniqueKeyLoader)


def _requirement_name(spec: str) -> str:
    return re.split(r"[<>=!~\[ ;]", spec.strip(), maxsplit=1)[0].lower().replace("_", "-")


def _conda_pip_section() -> list[str]:
    env = yaml.safe_load((REPO / "envs" / "dexlite.yaml").read_text())
    return next(d["pip"] for d in env["dependencies"] if isinstance(d, dict) and "pip" in d)


def test_conda_env_lists_exactly_the_package_dependencies():
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11
    requirements = [line for line in _conda_pip_section() if not line.startswith("-")]  # not pip options
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    assert sorted(map(_requirement_name, requirements)) == sorted(map(_requirement_name, project["dependencies"]))
    post_deploy = REPO / "envs" / "dexlite.post-deploy.sh"
    assert post_deploy.is_file() and "--no-deps" in post_deploy.read_text()


def test_conda_env_and_install_script_pin_the_same_cpu_torch():
    """Both install torch's CPU build (PyPI's torch is a CUDA build of several GB), of one version."""
    install_script = (REPO / "install.sh").read_text()
    version = re.search(r"^TORCH_VERSION=(\S+)$", install_script, re.M).group(1)
    cpu_index = re.search(r"^TORCH_CPU_INDEX=(\S+)$", install_script, re.M).group(1)
    pip_section = _conda_pip_section()
    assert f"torch=={version}+cpu" in pip_section
    assert f"--extra-index-url {cpu_index}" in pip_section
    assert cpu_index.endswith("/whl/cpu")


def test_every_rule_file_is_included():
    snakefile = (REPO / "Snakefile").read_text()
    for path in RULE_FILES:
        assert f'include: "{path.relative_to(REPO)}"' in snakefile, f"{path.name} is not included in the Snakefile"
