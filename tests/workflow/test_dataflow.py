"""docs/design.md's "Data flow" is what the Snakefile plans (tests/workflow/dataflow.py generates it)."""

from __future__ import annotations

import pytest
from dataflow import DESIGN_DOC, MARKERS, REGENERATE, collapse, data_flow, doc_parts, generated_section


def test_shard_and_round_numbers_collapse_to_wildcards():
    assert collapse("results/round_12/train/sample_003.zarr") == "results/round_{r}/train/sample_{shard}.zarr"
    assert collapse("results/post/random_shard_001.zarr") == "results/post/random_shard_{shard}.zarr"
    assert collapse("results/curate/summary_000.csv") == "results/curate/summary_{shard}.csv"
    assert collapse("results/model/cvae.pt") == "results/model/cvae.pt"


def test_the_flow_lists_writers_and_readers_in_data_flow_order():
    jobs = [
        ("train", ["results/lift/shard_000.zarr", "data/meshes/a.obj"], ["results/model/cvae.pt"]),
        ("lift", [], ["results/lift/shard_000.zarr"]),
        ("lift", [], ["results/lift/shard_001.zarr"]),
        ("sample", ["results/model/cvae.pt", "results/lift/shard_001.zarr"], ["results/sample/shard_001.zarr"]),
    ]
    rules, writers, readers = data_flow(jobs)
    assert rules == ["lift", "train", "sample"]
    assert writers == {"results/lift/shard_{shard}.zarr": ["lift"], "results/model/cvae.pt": ["train"], "results/sample/shard_{shard}.zarr": ["sample"]}
    assert readers == {"results/lift/shard_{shard}.zarr": ["train", "sample"], "results/model/cvae.pt": ["sample"], "results/sample/shard_{shard}.zarr": []}


@pytest.mark.slow
def test_design_doc_shows_the_data_flow():
    text = DESIGN_DOC.read_text()
    assert all(marker in text for marker in MARKERS), "docs/design.md lost its data flow markers"
    assert doc_parts(text)[1] == generated_section(), f"docs/design.md's data flow is stale: run {REGENERATE}"
