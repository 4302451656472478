"""The benchmark scripts are files, not package modules: tests load them by name from benchmarks/timing/ or
benchmarks/experiments/."""

import importlib.util
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
FOLDERS = ("timing", "experiments")


def load_benchmark(name: str):
    """The module of ``benchmarks/timing/<name>.py`` or ``benchmarks/experiments/<name>.py``, freshly executed."""
    paths = [BENCHMARKS / folder / f"{name}.py" for folder in FOLDERS if (BENCHMARKS / folder / f"{name}.py").is_file()]
    assert len(paths) == 1, f"benchmarks/{{{','.join(FOLDERS)}}}/{name}.py: {len(paths)} scripts of that name"
    spec = importlib.util.spec_from_file_location(name, paths[0])
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="session")
def benchmark_script():
    """``benchmark_script(name)``: the module of the benchmark script ``<name>.py`` (timing or experiments)."""
    return load_benchmark
