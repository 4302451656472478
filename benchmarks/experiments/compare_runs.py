"""Compare two pipeline runs' results folders value for value: did a code change move any result?

    python benchmarks/experiments/compare_runs.py BEFORE/results AFTER/results [--rename-path OLD=NEW ...]
        [--rename-column OLD=NEW ...] [--rename-value OLD=NEW ...] [--ignore-columns REGEX]

Compared, for every file found under both folders (after renaming BEFORE's paths):
- tables (.csv, .parquet): the same rows in the same order; every shared column's cells equal as text (CSV) or as values
  (Parquet, NaN equal to NaN). Columns matching --ignore-columns (wall and CPU time, which no two runs share) are left
  out and listed; columns only one side has (a feature that added a column) are listed, not compared.
- Zarr stores: every array both have, equal in shape, dtype and every value (NaN equal to NaN). Attributes (the
  recorded config, timings) are not compared.
- model checkpoints (.pt): every tensor of the state dicts equal.
Pictures, HTML pages, logs and JSON records (configs, run facts) are skipped: they carry dates, paths and key names.

Renames map BEFORE's names onto AFTER's: --rename-path replaces a whole path component (a folder or file stem),
--rename-column replaces a substring of column names and of Zarr array names, --rename-value replaces a whole text cell
or text array element (e.g. a method label).
Exit status 0 when everything compared is equal, 1 when something differs, 2 on bad arguments.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd

DEFAULT_IGNORED_COLUMNS = r"seconds|wall|cpu_s|_time|time_s$|per_s$"
TABLE_SUFFIXES = {".csv", ".parquet"}


def parse_pairs(pairs: list[str], flag: str) -> dict[str, str]:
    mapping = {}
    for pair in pairs:
        old, sep, new = pair.partition("=")
        if not sep or not old:
            raise SystemExit(f"compare_runs.py: error: {flag} takes OLD=NEW, got {pair!r}")
        mapping[old] = new
    return mapping


def renamed_path(relative: Path, path_renames: dict[str, str]) -> Path:
    parts = []
    for part in relative.parts:
        stem, dot, suffix = part.partition(".")
        parts.append(path_renames.get(part, path_renames.get(stem, stem) + dot + suffix))
    return Path(*parts)


def leaf_items(root: Path) -> dict[Path, Path]:
    """Relative path -> path for tables, checkpoints and Zarr stores (a store is one item, not its chunk files)."""
    items = {}
    for path in sorted(root.rglob("*")):
        if any(parent.suffix == ".zarr" for parent in path.relative_to(root).parents):
            continue
        if path.suffix == ".zarr" or (path.is_file() and path.suffix in TABLE_SUFFIXES | {".pt"}):
            items[path.relative_to(root)] = path
    return items


def read_table(path: Path) -> pd.DataFrame:
    if path.suffix == ".csv":
        return pd.read_csv(path, dtype=str, keep_default_na=False)
    return pd.read_parquet(path)


def compare_tables(before: Path, after: Path, args: argparse.Namespace) -> list[str]:
    old, new = read_table(before), read_table(after)
    old.columns = [renamed_name(c, args.column_renames) for c in old.columns]
    old = old.apply(lambda col: col.map(lambda v: args.value_renames.get(v, v) if isinstance(v, str) else v))
    problems = []
    if len(old) != len(new):
        return [f"{len(old)} rows before, {len(new)} after"]
    ignored = re.compile(args.ignore_columns)
    shared = [c for c in new.columns if c in set(old.columns)]
    skipped = [c for c in shared if ignored.search(c)]
    only_before = sorted(set(old.columns) - set(new.columns))
    only_after = sorted(set(new.columns) - set(old.columns))
    args.notes.append(f"{after.name}: {len(shared) - len(skipped)} columns compared, ignored {skipped or 'none'}, "
                      f"only before {only_before or 'none'}, only after {only_after or 'none'}")
    for column in shared:
        if column in skipped:
            continue
        left, right = old[column].reset_index(drop=True), new[column].reset_index(drop=True)
        equal = left.eq(right) | (left.isna() & right.isna())
        if not equal.all():
            row = int(np.flatnonzero(~equal.to_numpy())[0])
            problems.append(f"column {column}: {int((~equal).sum())} cells differ (row {row}: {left[row]!r} vs {right[row]!r})")
    return problems


def renamed_name(name: str, name_renames: dict[str, str]) -> str:
    for source, target in name_renames.items():
        name = name.replace(source, target)
    return name


def compare_zarr(before: Path, after: Path, value_renames: dict[str, str], name_renames: dict[str, str]) -> list[str]:
    import zarr

    old, new = zarr.open_group(str(before), mode="r"), zarr.open_group(str(after), mode="r")
    old_arrays = {renamed_name(name, name_renames): array for name, array in old.arrays()}
    new_arrays = dict(new.arrays())
    problems = [f"array {name} only before" for name in sorted(set(old_arrays) - set(new_arrays))]
    for name in sorted(set(old_arrays) & set(new_arrays)):
        left, right = old_arrays[name][...], new_arrays[name][...]
        if left.dtype.kind in "OUST" and value_renames:  # text labels (a method or origin) renamed like table cells
            left = np.vectorize(lambda v: value_renames.get(v, v), otypes=[left.dtype])(left) if left.size else left
        if left.shape != right.shape or left.dtype != right.dtype:
            problems.append(f"array {name}: {left.shape} {left.dtype} before, {right.shape} {right.dtype} after")
        elif not np.array_equal(left, right, equal_nan=left.dtype.kind in "fc"):
            problems.append(f"array {name}: {int(np.sum(left != right))} values differ")
    return problems


def compare_checkpoints(before: Path, after: Path) -> list[str]:
    import torch

    def tensors(path: Path) -> dict:
        checkpoint = torch.load(path, map_location="cpu", weights_only=False)
        state = checkpoint.get("model_state", checkpoint.get("state_dict", checkpoint)) if isinstance(checkpoint, dict) else checkpoint
        return {k: v for k, v in state.items() if isinstance(v, torch.Tensor)}

    old, new = tensors(before), tensors(after)
    if set(old) != set(new):
        return [f"tensor names differ: {sorted(set(old) ^ set(new))[:5]}"]
    return [f"tensor {k} differs" for k in sorted(old) if not torch.equal(old[k], new[k])]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--rename-path", action="append", default=[], metavar="OLD=NEW")
    parser.add_argument("--rename-column", action="append", default=[], metavar="OLD=NEW")
    parser.add_argument("--rename-value", action="append", default=[], metavar="OLD=NEW")
    parser.add_argument("--ignore-columns", default=DEFAULT_IGNORED_COLUMNS, help="regex of column names not compared (default %(default)r)")
    args = parser.parse_args(argv)
    for folder in (args.before, args.after):
        if not folder.is_dir():
            parser.error(f"{folder} is not a folder")
    path_renames = parse_pairs(args.rename_path, "--rename-path")
    args.column_renames = parse_pairs(args.rename_column, "--rename-column")
    args.value_renames = parse_pairs(args.rename_value, "--rename-value")
    args.notes = []

    before = {renamed_path(rel, path_renames): path for rel, path in leaf_items(args.before).items()}
    after = leaf_items(args.after)
    differing = 0
    for rel in sorted(set(before) | set(after)):
        if rel not in after or rel not in before:
            print(f"only {'before' if rel in before else 'after'}: {rel}")
            continue
        if rel.suffix == ".zarr":
            problems = compare_zarr(before[rel], after[rel], args.value_renames, args.column_renames)
        elif rel.suffix == ".pt":
            problems = compare_checkpoints(before[rel], after[rel])
        else:
            problems = compare_tables(before[rel], after[rel], args)
        differing += bool(problems)
        print(f"{'DIFFERS' if problems else 'equal  '} {rel}")
        for problem in problems:
            print(f"    {problem}")
    for note in args.notes:
        print(f"note: {note}")
    compared = len(set(before) & set(after))
    print(f"{compared} items compared, {differing} differ")
    return 1 if differing else 0


if __name__ == "__main__":
    sys.exit(main())
