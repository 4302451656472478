"""benchmarks/timing/run_all.py is importable and produces a table on small sizes."""

import math

import pytest


@pytest.fixture
def run_all(benchmark_script):
    return benchmark_script("run_all")


def test_object_scaling_quick(run_all, tmp_path):
    rows = run_all.run_benchmarks(quick=True, only=["object_scaling"], workdir=tmp_path)
    assert [(r.size, r.note) for r in rows] == [
        ("2 objects", "energies"), ("2 objects", "lift test, 1 thread"), ("4 objects", "energies"), ("4 objects", "lift test, 1 thread"),
    ]
    assert all(r.unit == "s" and math.isfinite(r.value) and r.value > 0 for r in rows)
    table = run_all.format_table(rows)
    assert table.count("\n") == len(rows) + 1 and "wall time vs objects" in table


def test_component_modules_are_discovered(run_all):
    names = set(run_all.external_benchmarks())
    assert {"energy", "lift", "post_optimize"} <= names


def test_unknown_benchmark_is_an_error(run_all, tmp_path):
    try:
        run_all.run_benchmarks(quick=True, only=["no_such_thing"], workdir=tmp_path)
    except ValueError as exc:
        assert "no_such_thing" in str(exc)
    else:
        raise AssertionError("unknown benchmark accepted")
