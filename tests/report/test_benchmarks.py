"""benchmarks/run_all.py is importable and produces a table on small sizes."""

import importlib.util
import math
import sys
from pathlib import Path

RUN_ALL = Path(__file__).resolve().parents[2] / "benchmarks" / "run_all.py"


def _load():
    spec = importlib.util.spec_from_file_location("run_all", RUN_ALL)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def test_object_scaling_quick(tmp_path):
    run_all = _load()
    rows = run_all.run_benchmarks(quick=True, only=["object_scaling"], workdir=tmp_path)
    assert [(r.size, r.note) for r in rows] == [
        ("2 objects", "energies"), ("2 objects", "lift test, 1 thread"), ("4 objects", "energies"), ("4 objects", "lift test, 1 thread"),
    ]
    assert all(r.unit == "s" and math.isfinite(r.value) and r.value > 0 for r in rows)
    table = run_all.format_table(rows)
    assert table.count("\n") == len(rows) + 1 and "wall time vs objects" in table


def test_component_modules_are_discovered():
    names = set(_load().external_benchmarks())
    assert {"energy", "lift", "post_optimize"} <= names


def test_unknown_benchmark_is_an_error(tmp_path):
    run_all = _load()
    try:
        run_all.run_benchmarks(quick=True, only=["no_such_thing"], workdir=tmp_path)
    except ValueError as exc:
        assert "no_such_thing" in str(exc)
    else:
        raise AssertionError("unknown benchmark accepted")
