"""``dexlite grasp`` from a built wheel in a fresh virtual environment: the shipped models (the Shadow Hand's and every
other hand's that ships, ``--hand``) and the default config come with the package, not from a checkout.

The wheel is built offline from a copy of the source (``pip wheel --no-deps --no-build-isolation``),
installed without dependencies into a new virtual environment that sees this environment's packages
(torch, mujoco, ...: ``--system-site-packages``, and this interpreter's site-packages when it is itself a
virtual environment), and run from a folder outside the checkout with no PYTHONPATH.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest
import trimesh

from dexlite_pipeline.config import default_config
from dexlite_pipeline.io.grasp_store import read_grasp_store
from dexlite_pipeline.model.shipped import SHIPPED_MODEL_DIR, SHIPPED_MODEL_DIRS, shipped_model_path

ROOT = Path(__file__).resolve().parents[2]
# A small budget: this checks the installation, not the grasps.
TINY = {
    "objects": {"sdf_resolution": 32, "surface_points": 512, "coacd_mcts_iterations": 10, "coacd_mcts_nodes": 5,
                "coacd_mcts_max_depth": 1, "coacd_resolution": 300},
    "energy": {"object_point_spacing_m": 0.004},
    "optimize_grasps": {"annealing": {"iterations": 60}, "final_contact_samples": 32, "contact_search_every": 0},
    "post_optimize": {"annealing": {"iterations": 5}, "energy_point_spacing_m": 0.004, "start_contact_samples": 8, "final_contact_samples": 8},
}  # fmt: skip


def _clean_environment() -> dict:
    environment = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    return {**environment, "PIP_NO_INDEX": "1", "PIP_DISABLE_PIP_VERSION_CHECK": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def _build_wheel(folder: Path) -> Path:
    """The package's wheel, built offline from a copy of the source (so the checkout gets no build files)."""
    source = folder / "source"
    source.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, source / name)
    shutil.copytree(ROOT / "src", source / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    wheels = folder / "wheels"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-q", "-w", str(wheels), str(source)],
        check=True, env=_clean_environment(), capture_output=True,
    )  # fmt: skip
    (wheel,) = wheels.glob("dexlite_pipeline-*.whl")
    return wheel


def _fresh_environment(folder: Path) -> Path:
    """A new virtual environment that sees this environment's packages but not its dexlite_pipeline; returns its python."""
    target = folder / "venv"
    venv.EnvBuilder(system_site_packages=True, with_pip=False).create(target)
    python = target / "bin" / "python"
    site_packages = Path(subprocess.run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                                        check=True, capture_output=True, text=True, env=_clean_environment()).stdout.strip())  # fmt: skip
    if sys.prefix != sys.base_prefix:  # this interpreter is a virtual environment: its packages by path (not its .pth files,
        # which hold an editable install of the checkout)
        (site_packages / "outer_environment.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    return python


@pytest.mark.slow
def test_a_wheel_in_a_fresh_environment_grasps_with_the_shipped_model(tmp_path):
    wheel = _build_wheel(tmp_path)
    names = set(zipfile.ZipFile(wheel).namelist())
    shipped_dir = f"dexlite_pipeline/data/{SHIPPED_MODEL_DIR}"
    for packaged in ("dexlite_pipeline/data/config.yaml", f"{shipped_dir}/cvae.pt", f"{shipped_dir}/evaluator.pt", f"{shipped_dir}/card.json",
                     "dexlite_pipeline/schemas/config.schema.yaml"):  # fmt: skip
        assert packaged in names
    # the object splits: read by the object lists (``held_out_household_ids`` among them) wherever the package is
    splits = sorted(f"dexlite_pipeline/objects/{p.name}" for p in (ROOT / "src" / "dexlite_pipeline" / "objects").glob("*_split.yaml"))
    assert len(splits) >= 3 and not set(splits) - names, sorted(set(splits) - names)
    python = _fresh_environment(tmp_path)
    subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps", "--no-index", "-q", str(wheel)],
                   check=True, env=_clean_environment(), capture_output=True)  # fmt: skip
    installed = subprocess.run([python, "-c", "import dexlite_pipeline; print(dexlite_pipeline.__file__)"], check=True,
                               capture_output=True, text=True, env=_clean_environment(), cwd=tmp_path).stdout.strip()  # fmt: skip
    package = Path(installed).parent
    assert package.is_relative_to(tmp_path / "venv"), f"dexlite_pipeline imported from {installed}, not the fresh environment"

    trimesh.creation.box((0.08, 0.06, 0.10)).export(tmp_path / "box.obj")
    out = tmp_path / "out"
    run = subprocess.run(
        [python.parent / "dexlite", "grasp", "box.obj", "--out", str(out), "--n", "2", "--renders", "0", "--threads", "1",
         "--top-up-batches", "1", "--config-json", json.dumps(TINY)],
        capture_output=True, text=True, env=_clean_environment(), cwd=tmp_path,
    )  # fmt: skip
    assert run.returncode in (0, 1), run.stderr[-2000:]
    every = read_grasp_store(out / "all_grasps.zarr")
    model = every.arrays["source"] == "model"  # 2 grasps give at most 2 distinct held ones: one batch of optimization tops them up
    assert every.arrays["method"][model].tolist() == ["cvae_post"] * 2 and every.arrays["method"][~model].tolist() == ["optimization"] * 2
    shipped = package / "data" / SHIPPED_MODEL_DIR / "cvae.pt"
    assert f"model: {shipped}" in (out / "summary.md").read_text()
    assert every.attrs["evaluator"] == str(shipped.with_name("evaluator.pt"))  # the shipped evaluator ranks the shipped model's samples
    assert every.attrs["config"]["lift"] == json.loads(json.dumps(default_config()["lift"]))  # the packaged default config

    for hand in [h for h in SHIPPED_MODEL_DIRS if h != "shadow" and shipped_model_path(h) is not None]:  # another hand's model
        folder = SHIPPED_MODEL_DIRS[hand]
        assert {f"dexlite_pipeline/data/{folder}/{name}" for name in ("cvae.pt", "evaluator.pt", "card.json")} <= names
        out = tmp_path / f"out_{hand}"
        run = subprocess.run(
            [python.parent / "dexlite", "grasp", "box.obj", "--out", str(out), "--n", "2", "--renders", "0", "--threads", "1",
             "--top-up-batches", "1", "--hand", hand, "--config-json", json.dumps(TINY)],
            capture_output=True, text=True, env=_clean_environment(), cwd=tmp_path,
        )  # fmt: skip
        assert run.returncode in (0, 1), run.stderr[-2000:]
        every = read_grasp_store(out / "all_grasps.zarr")
        assert every.attrs["hand"] == hand and every.hand_pose.shape[1] == 6 + len(every.attrs["joint_names"])
        assert f"model: {package / 'data' / folder / 'cvae.pt'}" in (out / "summary.md").read_text()
        assert every.attrs["evaluator"] == str(package / "data" / folder / "evaluator.pt")
