"""Compare the results/ trees of two runs of the same config (local vs SLURM, resumed vs whole).

Content is compared, not bytes: grasp stores array by array and attribute by attribute,
tables column by column, checkpoints tensor by tensor. Only what measures the machine
rather than the computation is left out: wall-clock timings (names with "second", "time",
"duration", "elapsed", "date", "host") and rendered images/HTML (they embed those timings).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd

MACHINE_DEPENDENT = re.compile(r"second|time|duration|elapsed|date|host|throughput|per_s\b|_per_hour", re.I)
NOT_COMPARED_SUFFIXES = {".png", ".html", ".svg", ".log"}


def result_entries(results: Path) -> list[Path]:
    """Outputs under ``results`` as relative paths: files, and Zarr stores as one entry each."""
    entries = []
    for path in sorted(results.rglob("*")):
        rel = path.relative_to(results)
        if any(part.endswith(".zarr") for part in rel.parts[:-1]) or any(".tmp-" in part for part in rel.parts):
            continue
        if path.is_file() or path.suffix == ".zarr":
            entries.append(rel)
    return entries


def _json_without_timings(value):
    if isinstance(value, dict):
        return {k: _json_without_timings(v) for k, v in value.items() if not MACHINE_DEPENDENT.search(str(k))}
    if isinstance(value, list):
        return [_json_without_timings(v) for v in value]
    return value


def _arrays_equal(a: np.ndarray, b: np.ndarray) -> bool:
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    if np.issubdtype(a.dtype, np.floating):
        return bool(np.array_equal(a, b, equal_nan=True))
    return bool(np.array_equal(a, b))


def _zarr_differences(a: Path, b: Path) -> list[str]:
    import warnings

    import zarr

    with warnings.catch_warnings():
        # Snakemake stamps directory outputs with a `.snakemake_timestamp` file zarr does not know.
        warnings.filterwarnings("ignore", message=r"Object at \.snakemake_timestamp")
        ga, gb = zarr.open_group(str(a), mode="r"), zarr.open_group(str(b), mode="r")
        return _open_group_differences(a, b, ga, gb)


def _open_group_differences(a: Path, b: Path, ga, gb) -> list[str]:
    problems = []
    if _json_without_timings(dict(ga.attrs)) != _json_without_timings(dict(gb.attrs)):
        problems.append("attributes differ")
    names_a = sorted(name for name, _ in ga.arrays())
    names_b = sorted(name for name, _ in gb.arrays())
    if names_a != names_b:
        return problems + [f"arrays {names_a} vs {names_b}"]
    for name in names_a:
        if MACHINE_DEPENDENT.search(name):
            continue
        if not _arrays_equal(np.asarray(ga[name][...]), np.asarray(gb[name][...])):
            problems.append(f"array {name} differs")
    groups_a = sorted(name for name, _ in ga.groups())
    if groups_a != sorted(name for name, _ in gb.groups()):
        problems.append("subgroups differ")
    for name in groups_a:
        problems += [f"{name}/{p}" for p in _zarr_differences(a / name, b / name)]
    return problems


def _table_differences(a: Path, b: Path) -> list[str]:
    read = pd.read_parquet if a.suffix == ".parquet" else pd.read_csv
    ta, tb = read(a), read(b)
    keep = [c for c in ta.columns if not MACHINE_DEPENDENT.search(str(c))]
    if list(ta.columns) != list(tb.columns):
        return [f"columns {list(ta.columns)} vs {list(tb.columns)}"]
    try:
        pd.testing.assert_frame_equal(ta[keep], tb[keep], check_exact=True)
    except AssertionError as exc:
        return [str(exc).splitlines()[0]]
    return []


def _checkpoint_differences(a: Path, b: Path) -> list[str]:
    import torch

    def tensors(path):
        loaded = torch.load(path, map_location="cpu", weights_only=False)
        flat = {}

        def walk(prefix, value):
            if isinstance(value, torch.Tensor):
                flat[prefix] = value
            elif isinstance(value, dict):
                for k, v in value.items():
                    if not MACHINE_DEPENDENT.search(str(k)):
                        walk(f"{prefix}/{k}", v)

        walk("", loaded)
        return flat

    ta, tb = tensors(a), tensors(b)
    if sorted(ta) != sorted(tb):
        return ["tensor names differ"]
    return [f"tensor {k} differs" for k in ta if not torch.equal(ta[k], tb[k])]


def entry_differences(a: Path, b: Path) -> list[str]:
    """Why two outputs of the same name differ in content (empty: equal)."""
    if a.suffix in NOT_COMPARED_SUFFIXES:
        return []
    if a.suffix == ".zarr":
        return _zarr_differences(a, b)
    if a.suffix in (".parquet", ".csv"):
        return _table_differences(a, b)
    if a.suffix == ".pt":
        return _checkpoint_differences(a, b)
    if a.suffix == ".json":
        same = _json_without_timings(json.loads(a.read_text())) == _json_without_timings(json.loads(b.read_text()))
        return [] if same else ["JSON content differs"]
    if a.suffix == ".tsv":
        return []
    return [] if a.read_bytes() == b.read_bytes() else ["bytes differ"]


def results_differences(results_a: Path, results_b: Path) -> dict[str, list[str]]:
    """Every output that is missing on one side or differs in content."""
    entries_a, entries_b = result_entries(results_a), result_entries(results_b)
    if not entries_a:
        raise FileNotFoundError(f"{results_a}: no outputs to compare")
    problems: dict[str, list[str]] = {}
    for rel in sorted(set(entries_a) ^ set(entries_b)):
        problems[str(rel)] = ["only in " + (str(results_a) if rel in entries_a else str(results_b))]
    for rel in sorted(set(entries_a) & set(entries_b)):
        found = entry_differences(results_a / rel, results_b / rel)
        if found:
            problems[str(rel)] = found
    return problems
