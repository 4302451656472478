"""The workflow's data flow: which rule writes each results/ path and which rules read it, from Snakemake itself.

A dry run of the real Snakefile (``snakemake --dry-run --forceall``) on config.yaml with the data loop on
(``loop.rounds: 2``, so that a round reads the one before it) and the committed grasp fixture as the
DexGraspNet download lists every job with its input and output paths. Shard and round numbers are collapsed
(``shard_000.zarr`` -> ``shard_{shard}.zarr``, ``round_1`` -> ``round_{r}``), so the picture does not
depend on ``shards`` or ``loop.rounds``; paths outside results/ (meshes, the download, the split files, the
shipped model) and the target rule ``all`` are left out. docs/design.md's "Data flow" is generated from here:
``PYTHONPATH=src .venv/bin/python tests/workflow/dataflow.py docs/design.md`` (tests/workflow/test_dataflow.py
fails when it is stale). The package itself never imports Snakemake; this module only runs it.
"""

from __future__ import annotations

import re
import tempfile
from functools import cache
from pathlib import Path

from workflow_harness import REPO, grasp_fixture, job_blocks, repo_config, run_snakemake, write_config

from dexlite_pipeline.config import merge_config

DESIGN_DOC = REPO / "docs" / "design.md"
MARKERS = ("<!-- data flow: start -->\n", "<!-- data flow: end -->")
REGENERATE = "PYTHONPATH=src .venv/bin/python tests/workflow/dataflow.py docs/design.md"
RESULTS = "results/"
# The representative config: config.yaml's own settings, plus the data loop, a DexGraspNet import and the learned evaluator.
LOOP_ROUNDS = 2
# A path read by more stages than this (the object catalog, the stability table) is drawn without its reading
# edges, which would cross the whole diagram; its node says how many stages read it, and the table names them.
DRAWN_READERS = 6
_SHARD = re.compile(r"(?<=_)\d{3}(?=\.\w+$)")
_ROUND = re.compile(r"(?<=/round_)\d+(?=/)")

Jobs = list[tuple[str, list[str], list[str]]]  # (rule, input paths, output paths) per planned job


def collapse(path: str) -> str:
    """A path with its shard and round numbers as wildcards: ``round_1/train/sample_003.zarr`` -> ``round_{r}/train/sample_{shard}.zarr``."""
    return _ROUND.sub("{r}", _SHARD.sub("{shard}", path))


def representative_config() -> dict:
    from dexlite_pipeline.evaluation.config import METHODS

    return merge_config(repo_config(), {"loop": {"rounds": LOOP_ROUNDS}, "dexgraspnet": {"root": str(grasp_fixture())},
                                        "evaluator": {"enabled": True}, "evaluate": {"methods": list(METHODS)}})


def _paths(field: str) -> list[str]:
    return [path for path in (part.strip() for part in field.split(",")) if path]


def planned_jobs(workdir: Path) -> Jobs:
    """Every job of a dry run in ``workdir`` (which holds the config), with its inputs and outputs, ``all`` left out."""
    output = run_snakemake(workdir, "--dry-run", "--forceall", "--cores", "2")
    jobs = [(block["rule"], _paths(block.get("input", "")), _paths(block.get("output", ""))) for block in job_blocks(output)]
    jobs = [job for job in jobs if job[0] != "all"]
    if not jobs:
        raise ValueError(f"no jobs in the dry-run output:\n{output[-3000:]}")
    return jobs


def rule_order(jobs: Jobs) -> list[str]:
    """The rules in data-flow order: by the longest chain of jobs before any of their jobs, then by name.

    Uses the job graph, whose numbered paths have no cycles (the collapsed paths of the data loop do)."""
    writer = {path: index for index, (_, _, outputs) in enumerate(jobs) for path in outputs}

    @cache
    def depth(index: int) -> int:
        before = {writer[path] for path in jobs[index][1] if path in writer}
        return 1 + max((depth(i) for i in before), default=-1)

    first: dict[str, int] = {}
    for index, (rule, _, _) in enumerate(jobs):
        first[rule] = min(first.get(rule, depth(index)), depth(index))
    return sorted(first, key=lambda rule: (first[rule], rule))


def data_flow(jobs: Jobs) -> tuple[list[str], dict[str, list[str]], dict[str, list[str]]]:
    """The rules in order, and per collapsed results/ path (in order) the rules that write it and those that read it.

    A collapsed path may have two writers: round 0's set of the data loop (``loop_initial_set``) and the later rounds' (``loop_merge``)."""
    rules = rule_order(jobs)
    position = {rule: index for index, rule in enumerate(rules)}
    written: dict[str, set[str]] = {}
    read: dict[str, set[str]] = {}
    for rule, inputs, outputs in jobs:
        for path in map(collapse, outputs):
            written.setdefault(path, set()).add(rule)
        for path in map(collapse, inputs):
            if path.startswith(RESULTS):
                read.setdefault(path, set()).add(rule)
    unwritten = sorted(set(read) - set(written))
    if unwritten:
        raise ValueError(f"results/ paths that no rule writes: {unwritten}")

    def in_order(names: set[str]) -> list[str]:
        return sorted(names, key=position.__getitem__)

    writers = {path: in_order(written[path]) for path in sorted(written, key=lambda p: (min(map(position.__getitem__, written[p])), p))}
    return rules, writers, {path: in_order(read.get(path, set())) for path in writers}


def _node(path: str) -> str:
    """The Mermaid id of a path's node: ``results/round_{r}/grasps.zarr`` -> ``f_round_r_grasps_zarr``."""
    return "f_" + re.sub(r"[\W_]+", "_", path.removeprefix(RESULTS)).strip("_")


def data_flow_markdown(jobs: Jobs) -> str:
    """docs/design.md's "Data flow": a Mermaid flowchart (rule -> path -> rule) and a table path | written by | read by."""
    rules, writers, readers = data_flow(jobs)
    if len({_node(path) for path in writers}) < len(writers):
        raise ValueError(f"two paths share a diagram node id: {sorted(writers, key=_node)}")
    lines = ["```mermaid", "flowchart TD"]
    lines += [f"    {rule}[{rule}]" for rule in rules]
    for path in writers:
        shared = f"<br>read by {len(readers[path])} stages: see the table" if len(readers[path]) > DRAWN_READERS else ""
        lines.append(f'    {_node(path)}[("{path.removeprefix(RESULTS)}{shared}")]')
    for path, written_by in writers.items():
        lines += [f"    {rule} --> {_node(path)}" for rule in written_by]
        if len(readers[path]) <= DRAWN_READERS:
            lines += [f"    {_node(path)} --> {reader}" for reader in readers[path]]
    lines += ["```", "", "| path | written by | read by |", "| --- | --- | --- |"]
    for path, written_by in writers.items():
        read_by = ", ".join(f"`{reader}`" for reader in readers[path]) or "—"
        lines.append(f"| `{path}` | {', '.join(f'`{rule}`' for rule in written_by)} | {read_by} |")
    return "\n".join(lines) + "\n"


def generated_section() -> str:
    """The section as the current Snakefile gives it (one dry run in a scratch folder, ~3 s)."""
    with tempfile.TemporaryDirectory(prefix="dexlite-dataflow-") as scratch:
        workdir = Path(scratch)
        write_config(workdir, representative_config())
        return data_flow_markdown(planned_jobs(workdir))


def doc_parts(text: str) -> tuple[str, str, str]:
    """The text before the start marker, between the markers, and after the end marker."""
    start, end = MARKERS
    head, rest = text.split(start, 1)
    listed, tail = rest.split(end, 1)
    return head, listed, tail


if __name__ == "__main__":
    import sys

    path = Path(sys.argv[1]) if len(sys.argv) > 1 else DESIGN_DOC
    head, _, tail = doc_parts(path.read_text())
    path.write_text(head + MARKERS[0] + generated_section() + MARKERS[1] + tail)
    print("regenerated", path)
