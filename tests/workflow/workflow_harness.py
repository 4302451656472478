"""Run the real Snakefile on a tiny config in a scratch directory, and read what it plans.

Shared by the rerun, resume and SLURM tests. Runs use a frozen copy of the checkout
(Snakefile, rules, profiles, config, package source on PYTHONPATH), taken once per test
session, so that code edited while the tests run cannot change their code hashes half-way.
``--directory`` points at a scratch folder that holds only ``config.yaml``; results, logs
and Snakemake's metadata all stay in that folder.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/: the shared sample_data module
from sample_data import FIXTURE_HELDOUT_OBJECT, GRASP_FIXTURE  # noqa: E402

import yaml

from dexlite_pipeline.config import merge_config
from dexlite_pipeline.evaluation.config import METHODS as EVALUATE_METHODS

REPO = Path(__file__).resolve().parents[2]
GRASP_FIXTURE_PART = GRASP_FIXTURE.relative_to(REPO).as_posix()
CHECKOUT_PARTS = ("Snakefile", "config.yaml", "config", "workflow", "profiles", "envs", "src", "pyproject.toml", GRASP_FIXTURE_PART)
_checkout: Path | None = None
BIN_DIR = Path(sys.executable).parent
# The smallest settings that still exercise every stage. Keys of sections that are not in
# config.yaml yet are ignored (stages land one by one); keys that are, must be valid.
TINY_OVERRIDES: dict = {
    "shards": 2,
    "objects": {
        "builtin_count": 0,
        "heldout_fraction": 0.34,
        "sdf_resolution": 32,
        "surface_points": 256,
        "coacd_max_convex_hull": 4,
        "benchmark_objects": 1,  # one object no model trained on: the shipped model's rows
    },
    # Real grasps to train on: a tiny optimization run finds none that hold, so the tiny config imports the
    # committed fixture of grasps the pipeline found and lift-tested itself, in DexGraspNet's layout
    # (grasp_fixture(), made by tests/fixtures/make_grasp_fixture.py; the mug is held out).
    "dexgraspnet": {"heldout_object_codes": [FIXTURE_HELDOUT_OBJECT]},
    "optimize_grasps": {
        "grasps_per_object": 2,
        "scales": [0.1],
        "batch_size": 16,
        "progress_every": 10,
        "annealing": {"iterations": 20}, "trace_every": 5,
    },
    "curate": {"max_grasps_per_object": 4},
    "energy": {"object_point_spacing_m": 0.004},
    "train": {
        "max_steps": 300,  # ~15 CPU s: a model that proposes grasps the data loop can refine into grasps that hold
        "batch_size": 8,
        "points_per_cloud": 64,
        "energy_point_spacing_m": 0.006,
        "min_grasps": 1,
        "model": {
            "pointnet_widths": [16, 32, 64, 32],
            "encoder_hidden": [32, 32],
            "decoder_hidden": [32, 32],
            "latent_dim": 8,
        },
    },
    "sample": {"synthesis_grasps_per_object": 4, "expansion_grasps_per_object": 2},
    # 128 steps (the default: 200): with 8, no sampled grasp of the tiny model came below the energy thresholds
    "post_optimize": {"annealing": {"iterations": 128}, "batch_size": 64, "energy_point_spacing_m": 0.006},
    "evaluate": {"grasps_per_object": 2, "rendered_per_method": 1, "pca_components": [1, 2], "methods": list(EVALUATE_METHODS)},
    # the learned evaluator, small: on-generator examples, training, ranked rows (cvae_ranked*)
    "evaluator": {"enabled": True, "examples_per_object": 4, "epochs": 3, "pool_factor": 2},
    # two rounds of the data loop (off by default), small, yet large enough that some grasp is kept
    "loop": {"rounds": 2, "grasps_per_object": 8, "train_steps": 20, "heldout_grasps_per_object": 2, "post_iterations": 256},
}

# Every rule gets one thread in the tests: two shards run side by side on two cores, and a
# local run and a SLURM run of the same config compute with the same thread counts.
TEST_THREADS = 1


def freeze_checkout(destination: Path) -> Path:
    """Copy the parts of the repository a workflow run reads to ``destination``; runs use it from now on."""
    global _checkout
    for part in CHECKOUT_PARTS:
        source = REPO / part
        if source.is_dir():
            shutil.copytree(source, destination / part, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        elif source.is_file():
            destination.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, destination / part)
    _checkout = destination
    return destination


def checkout() -> Path:
    """The frozen copy of the repository (the repository itself before freeze_checkout)."""
    return _checkout or REPO


def grasp_fixture() -> Path:
    """The committed grasp fixture in the frozen checkout (its DexGraspNet root)."""
    return checkout() / GRASP_FIXTURE_PART


def repo_config() -> dict:
    return yaml.safe_load((checkout() / "config.yaml").read_text())


def write_tiny_meshes(folder: Path) -> Path:
    """Three small primitive meshes (a box, a cylinder, a sphere) as .obj files in ``folder``.

    Simple shapes keep object preparation (CoACD, SDF) to seconds; the tiny config reads
    them through ``objects.mesh_dirs``, the path a user's own meshes take.
    """
    import trimesh

    folder.mkdir(parents=True, exist_ok=True)
    shapes = {
        "box": trimesh.creation.box(extents=(0.08, 0.06, 0.05)),
        "cylinder": trimesh.creation.cylinder(radius=0.03, height=0.09, sections=24),
        "sphere": trimesh.creation.icosphere(subdivisions=2, radius=0.04),
    }
    for name, mesh in shapes.items():
        mesh.export(folder / f"{name}.obj")
    return folder


def tiny_config(mesh_dir: Path, **section_overrides: dict) -> dict:
    """config.yaml with TINY_OVERRIDES (for the sections it has), the meshes of ``mesh_dir``
    as the objects, the grasp fixture as the DexGraspNet download, and then ``section_overrides``."""
    config = repo_config()
    applicable = {k: v for k, v in TINY_OVERRIDES.items() if k in config}
    config = merge_config(config, applicable)
    config["objects"]["mesh_dirs"] = [str(mesh_dir)]
    config["dexgraspnet"]["root"] = str(grasp_fixture())
    return merge_config(config, section_overrides)


def write_config(workdir: Path, config: dict) -> Path:
    workdir.mkdir(parents=True, exist_ok=True)
    path = workdir / "config.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=True))
    return path


def snakemake_env(extra: dict[str, str] | None = None) -> dict[str, str]:
    """The environment of a snakemake run: this venv's commands (snakemake, dexlite) first on
    PATH, the frozen checkout's package source first on PYTHONPATH (unless ``extra`` names one)."""
    env = {**os.environ, "PYTHONPATH": str(checkout() / "src"), **(extra or {})}
    env["PATH"] = f"{BIN_DIR}{os.pathsep}{env.get('PATH', '')}"
    env.pop("SNAKEMAKE_PROFILE", None)
    return env


def snakemake_command(workdir: Path, *args: str) -> list[str]:
    """The command line of a run in ``workdir``: with the Snakefile found there when ``workdir`` is a
    checkout itself (as a user runs it), else the frozen checkout's."""
    snakefile = workdir / "Snakefile" if (workdir / "Snakefile").is_file() else checkout() / "Snakefile"
    return [
        str(BIN_DIR / "snakemake"),
        "--snakefile", str(snakefile),
        "--directory", str(workdir),
        "--configfile", str(workdir / "config.yaml"),
        *args,
    ]


def run_snakemake(workdir: Path, *args: str, env: dict | None = None, timeout_s: float = 600) -> str:
    """Run snakemake to completion; raise with the tail of its output if it fails."""
    done = subprocess.run(
        snakemake_command(workdir, *args), env=snakemake_env(env), capture_output=True, text=True, timeout=timeout_s
    )
    output = done.stdout + done.stderr
    if done.returncode != 0:
        logs = "".join(
            f"\n--- {log.relative_to(workdir)}:\n{log.read_text()[-2000:]}"
            for log in sorted((workdir / "logs").glob("*.log")) if log.is_file()
        ) if (workdir / "logs").is_dir() else ""
        raise AssertionError(f"snakemake {' '.join(args)} failed ({done.returncode}):\n{output[-6000:]}{logs}")
    return output


def local_run_args(cores: int = 2) -> list[str]:
    """Cores and per-rule threads of a local test run (threads first: that option takes a list)."""
    return ["--set-threads", *(f"{rule}={TEST_THREADS}" for rule in rule_names()), "--cores", str(cores)]


_JOB_TABLE_ROW = re.compile(r"^(\S+)\s+(\d+)$")
_JOB_HEADER = re.compile(r"^(local)?(?:rule|checkpoint) (\w+):$")
_JOB_FIELD = re.compile(r"^\s+(\w+): (.*)$")


def job_blocks(output: str) -> list[dict[str, str]]:
    """The per-job blocks of Snakemake's output ("rule NAME:" then indented "key: value" lines).

    Each block is a dict with "rule", "local" ("yes" for a job run by the main process,
    e.g. a localrule under a cluster executor) plus its fields (output, wildcards, reason, ...).
    """
    blocks: list[dict[str, str]] = []
    current: dict[str, str] | None = None
    for line in output.splitlines():
        if header := _JOB_HEADER.match(line.strip()):
            current = {"rule": header.group(2), "local": "yes" if header.group(1) else "no"}
            blocks.append(current)
        elif current is not None and (field := _JOB_FIELD.match(line)):
            current.setdefault(field.group(1), field.group(2).strip())
        else:
            current = None
    return blocks


def planned_commands(output: str) -> dict[str, list[str]]:
    """Rule -> the shell commands of its jobs in a ``snakemake --dry-run --printshellcmds`` output."""
    commands: dict[str, list[str]] = {}
    rules = iter(block["rule"] for block in job_blocks(output))
    for line in output.splitlines():
        if line.startswith("Shell command: "):
            commands.setdefault(next(rules), []).append(line.removeprefix("Shell command: "))
    return commands


def option_value(command: str, option: str) -> str:
    """The value that ``option`` has in a shell command (before its log redirection)."""
    words = shlex.split(command.split(" > ")[0])
    return words[words.index(option) + 1]


def wildcard(block: dict[str, str], name: str) -> str | None:
    """Value of wildcard ``name`` in a job block, or None."""
    for item in block.get("wildcards", "").split(","):
        key, _, value = item.strip().partition("=")
        if key == name:
            return value
    return None


def parse_dry_run(output: str) -> Counter:
    """Jobs per rule that a ``snakemake -n`` output plans (empty when nothing is to be done).

    Reads the "Job stats" table and cross-checks it against the per-job blocks
    ("rule NAME:" headers), so a change of Snakemake's layout fails loudly instead of
    silently reading as "nothing planned".
    """
    lines = [line.rstrip() for line in output.splitlines()]
    blocks = Counter(block["rule"] for block in job_blocks(output))
    if "Job stats:" not in lines:
        if blocks or "Nothing to be done" not in output:
            raise ValueError(f"cannot read the dry-run output:\n{output[-3000:]}")
        return Counter()
    table: Counter = Counter()
    start = lines.index("Job stats:")
    for line in lines[start + 1:]:
        match = _JOB_TABLE_ROW.match(line.strip())
        if match is None:
            continue
        name, count = match.group(1), int(match.group(2))
        if name == "total":
            if count != sum(table.values()):
                raise ValueError(f"job table total {count} != sum of rows {sum(table.values())}")
            break
        table[name] = count
    else:
        raise ValueError(f"job table without a total line:\n{output[-3000:]}")
    if table != blocks:
        raise ValueError(f"job table {dict(table)} disagrees with job blocks {dict(blocks)}")
    return table


def planned_rules(workdir: Path, *args: str, env: dict | None = None) -> set[str]:
    """Rules that ``snakemake -n`` would run in ``workdir`` (the 'all' target rule excluded)."""
    output = run_snakemake(workdir, "--dry-run", "--cores", "2", *args, env=env)
    return set(parse_dry_run(output)) - {"all"}


def rule_names() -> list[str]:
    """Every rule the workflow defines (from ``snakemake --list-rules``)."""
    done = subprocess.run(
        [str(BIN_DIR / "snakemake"), "--snakefile", str(checkout() / "Snakefile"), "--cores", "2", "--list-rules"],
        env=snakemake_env(), capture_output=True, text=True, timeout=120, cwd=checkout(),
    )
    if done.returncode != 0:
        raise AssertionError(f"snakemake --list-rules failed: {done.stderr[-3000:]}")
    return [line.strip() for line in done.stdout.splitlines() if re.fullmatch(r"\s*\w+\s*", line)]


def rule_blocks() -> dict[str, str]:
    """Rule name -> the text of its definition, from every workflow/rules/*.smk file."""
    blocks = {}
    for path in sorted((checkout() / "workflow" / "rules").glob("*.smk")):
        for part in re.split(r"^(?=rule \w+:)", path.read_text(), flags=re.M):
            if match := re.match(r"rule (\w+):", part):
                blocks[match.group(1)] = re.split(r"^\S", part[match.end():], maxsplit=1, flags=re.M)[0]
    return blocks


def rule_code_modules() -> dict[str, list[str]]:
    """Rule name -> the modules its ``code=code_hash(...)`` param names (full dotted names)."""
    modules = {}
    for rule, body in rule_blocks().items():
        if call := re.search(r"code_hash\(([^)]*)\)", body):
            names = re.findall(r"[\"']([\w.]+)[\"']", call.group(1))
            modules[rule] = [n if "." in n else f"dexlite_pipeline.stages.{n}" for n in names]
    return modules


_DOT_NODE = re.compile(r'^\s*(\d+)\[label = "(\w+)"')
_DOT_EDGE = re.compile(r"^\s*(\d+) -> (\d+)")


def rule_graph(workdir: Path) -> dict[str, set[str]]:
    """Rule -> rules that consume its outputs, from ``snakemake --rulegraph`` (DOT)."""
    output = run_snakemake(workdir, "--rulegraph", "--forceall", "--cores", "2")
    names: dict[str, str] = {}
    consumers: dict[str, set[str]] = {}
    for line in output.splitlines():
        if match := _DOT_NODE.match(line):
            names[match.group(1)] = match.group(2)
            consumers.setdefault(match.group(2), set())
    for line in output.splitlines():
        if match := _DOT_EDGE.match(line):
            consumers[names[match.group(1)]].add(names[match.group(2)])
    if not names:
        raise ValueError(f"no rules in the rule graph output:\n{output[-2000:]}")
    return consumers


def downstream(graph: dict[str, set[str]], rules: set[str]) -> set[str]:
    """``rules`` and every rule that (transitively) consumes their outputs, the target rule 'all' left out."""
    found, pending = set(), list(rules)
    while pending:
        rule = pending.pop()
        if rule not in found:
            found.add(rule)
            pending.extend(graph.get(rule, ()))
    return found - {"all"}
