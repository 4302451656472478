"""Which objects a change of the preparation changes: this checkout's solids against another commit's, and every deviation.

For each object of the default run (pybullet_data's built-in objects and the benchmark split) and of the
household dataset (the household generator's objects), prepares the mesh file with this
checkout's ``prepared_solid`` and with ``--base``'s ``repair_mesh`` (read from git), compares
the two meshes (identical vertices and faces, or how far apart), and records this checkout's
route, refusals and prepared-versus-input deviation. Writes one CSV row per object and prints
the counts. No asset is built (no CoACD, no SDF): a few seconds per object.

    .venv/bin/python benchmarks/experiments/preparation_changes.py --base ac46b02 --out /tmp/preparation.csv
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def base_module(commit: str):
    """``objects/prepare.py`` at ``commit``, imported as its own module."""
    text = subprocess.run(["git", "show", f"{commit}:src/dexlite_pipeline/objects/prepare.py"], capture_output=True, text=True, check=True).stdout
    path = Path(tempfile.mkdtemp()) / "base_prepare.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("base_prepare", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def sources(household: int, builtin: int, benchmark: int, seed: int, folder: Path):
    from dexlite_pipeline.objects.sources import collect_sources

    default_run = collect_sources(builtin, [], [], seed, True, benchmark, 0, 0, folder, 0)
    dataset = collect_sources(0, [], [], seed, False, 0, household, 36, folder, 0)
    return [("default", s) for s in default_run] + [("dataset", s) for s in dataset]


def compare(old, new) -> tuple[bool, float]:
    """(identical vertices and faces, symmetric largest vertex distance / size)."""
    from scipy.spatial import cKDTree

    same = (np.asarray(old.faces).shape == np.asarray(new.faces).shape and np.array_equal(old.faces, new.faces)
            and np.array_equal(old.vertices, new.vertices))  # fmt: skip
    size = float(np.asarray(old.extents).max())
    gap = max(cKDTree(new.vertices).query(old.vertices)[0].max(), cKDTree(old.vertices).query(new.vertices)[0].max())
    return bool(same), float(gap) / size


def main() -> int:
    import pandas as pd

    from dexlite_pipeline.objects.asset_building import MeshRejected, check_shape, load_source_mesh, prepared_solid

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--base", required=True, help="commit whose repair_mesh + check_mesh is the reference")
    parser.add_argument("--out", required=True, help="CSV, one row per object")
    parser.add_argument("--household", type=int, default=440, help="household dataset objects (the dataset's 440 by default)")
    parser.add_argument("--builtin", type=int, default=40, help="pybullet_data objects of the default run")
    parser.add_argument("--benchmark", type=int, default=48, help="benchmark-split objects (the default run holds out 4, the household profile 48)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    base = base_module(args.base)
    rows = []
    todo = sources(args.household, args.builtin, args.benchmark, args.seed, Path(tempfile.mkdtemp()))
    start = time.perf_counter()
    for k, (group, source) in enumerate(todo):
        row = {"group": group, "object_id": source.object_id}
        raw = load_source_mesh(source)
        try:
            check_shape(raw)
            old = base.repair_mesh(raw.copy())
            base.check_mesh(old)
        except base.MeshRejected as exc:
            old, row["base_reason"] = None, str(exc)
        try:
            new, record, deviation = prepared_solid(raw.copy(), source.metres_per_unit)
            row.update(route=record.summary(), notes="; ".join(record.notes), **deviation.as_record())
        except MeshRejected as exc:
            new, row["reason"] = None, str(exc)
        if old is not None and new is not None:
            row["identical"], row["largest_vertex_gap"] = compare(old, new)
            row["volume_change"] = float(new.volume / old.volume - 1.0)
        rows.append(row)
        if (k + 1) % 25 == 0:
            elapsed = time.perf_counter() - start
            print(f"{k + 1}/{len(todo)} objects, {elapsed / (k + 1):.2f} s each, ~{elapsed / (k + 1) * (len(todo) - k - 1):.0f} s left", file=sys.stderr)
    table = pd.DataFrame(rows)
    table.to_csv(args.out, index=False)
    for group, part in table.groupby("group"):
        both = part["identical"].notna()
        print(f"{group}: {len(part)} objects; identical {int(part['identical'].fillna(False).sum())} of {int(both.sum())} prepared by both; "
              f"refused now {int(part.get('reason', pd.Series(dtype=str)).notna().sum())}, refused before {int(part.get('base_reason', pd.Series(dtype=str)).notna().sum())}; "
              f"surface p99 deviation median {part['surface_p99_in_to_prepared'].median():.2e}, max {part['surface_p99_in_to_prepared'].max():.2e}")  # fmt: skip
        changed = part[both & ~part["identical"].fillna(True).astype(bool)]
        for r in changed.itertuples():
            print(f"  changed {r.object_id}: largest vertex gap {r.largest_vertex_gap:.2e} of the size, volume {100 * r.volume_change:+.2f}%, {r.route}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
