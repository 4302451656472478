"""Exact reruns: after a complete run, `snakemake -n` plans exactly the stages a change affects.

Expected plans come from two places that must agree: the rule graph (the changed stage and
everything that consumes its outputs, transitively) and the pipeline's design (which named
stages must and must not rerun).
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import pytest
from workflow_harness import (
    checkout,
    downstream,
    option_value,
    planned_commands,
    planned_rules,
    rule_code_modules,
    run_snakemake,
    tiny_config,
    write_config,
)

from dexlite_pipeline.codehash import module_closure
from dexlite_pipeline.config import ConfigError, validate_config

pytestmark = pytest.mark.slow

UPSTREAM_OF_LIFT = {"prepare_objects", "stability_filter", "optimize_grasps", "import_dexgraspnet", "curate"}
UPSTREAM_OF_TRAINING = UPSTREAM_OF_LIFT | {"lift_validate"}
UPSTREAM_OF_POST = UPSTREAM_OF_TRAINING | {"train_cvae", "sample_grasps"}


@dataclass(frozen=True)
class ConfigChange:
    section: str  # the config section changed
    key: str  # the numeric key changed in it (dotted for a nested key)
    stages: frozenset[str]  # the rules that read it
    must_rerun: frozenset[str]
    must_not_rerun: frozenset[str]


CHANGES = [
    # a post-optimization setting: post_optimize (the data loop's too) and the evaluation, nothing before the first model;
    # sampling reruns too, because the loop's rounds post-optimize and the final model it samples from changes
    ConfigChange(
        "post_optimize", "annealing.iterations", frozenset({"post_optimize", "loop_post_optimize"}),
        frozenset({"post_optimize", "loop_post_optimize", "loop_train", "sample_grasps", "evaluate"}),
        frozenset(UPSTREAM_OF_TRAINING | {"train_cvae"}),
    ),
    # a lift-test constant: the lift stages and everything that depends on them
    ConfigChange("lift", "friction", frozenset({"lift_validate"}), frozenset({"lift_validate", "train_cvae", "evaluate"}), frozenset(UPSTREAM_OF_LIFT)),
    # a training setting: training and everything downstream of it
    ConfigChange(
        "train", "max_steps", frozenset({"train_cvae"}), frozenset({"train_cvae", "sample_grasps", "post_optimize", "evaluate"}),
        frozenset(UPSTREAM_OF_TRAINING),
    ),
    # the training seed alone (training seeds on the same data): the training and what follows it, no data stage
    ConfigChange(
        "train", "seed", frozenset({"train_cvae"}), frozenset({"train_cvae", "sample_grasps", "post_optimize", "evaluate"}),
        frozenset(UPSTREAM_OF_TRAINING),
    ),
]


# Settings that cannot change any output (log cadence; the batch size of energy evaluation,
# which is per grasp) reach their stage but rerun nothing.
# (section, key, a rule that reads it)
RESULT_NEUTRAL_KEYS = [
    ("optimize_grasps", "progress_every", "optimize_grasps"),
    ("curate", "energy_batch_size", "curate"),
    ("evaluate", "energy_batch_size", "evaluate_simulate"),
]


def _numeric_variants(value):
    if isinstance(value, bool):
        return []
    if isinstance(value, int):
        return [value + 1, value - 1]
    if isinstance(value, float):
        return [value * 1.5, value * 0.5, value + 0.1]
    return []


def _with_value(mapping: dict, path: list[str], value) -> dict:
    """A copy of ``mapping`` with the nested key ``path`` set to ``value``."""
    head, *rest = path
    return {**mapping, head: _with_value(mapping[head], rest, value) if rest else value}


def changed_config(config: dict, section: str, key: str) -> tuple[str, dict]:
    """``config`` with ``section.key`` (``key`` may be dotted) changed to another value the schema accepts."""
    path = [section, *key.split(".")]
    value = config
    for part in path:
        value = value[part]
    for variant in _numeric_variants(value):
        candidate = _with_value(config, path, variant)
        try:
            validate_config(candidate)
        except ConfigError:
            continue
        return f"{section}.{key}: {value!r} -> {variant!r}", candidate
    raise AssertionError(f"no valid change of numeric config key {section}.{key} = {value!r}")


def test_unchanged_config_plans_nothing(complete_run):
    assert planned_rules(complete_run.workdir) == set()


@pytest.mark.parametrize("change", CHANGES, ids=lambda c: f"{c.section}.{c.key}")
def test_config_change_reruns_exactly_the_affected_stages(complete_run, scratch_copy, change):
    graph = complete_run.graph
    description, config = changed_config(complete_run.config, change.section, change.key)
    write_config(scratch_copy, config)

    planned = planned_rules(scratch_copy)

    assert planned == downstream(graph, set(change.stages)), description
    assert change.must_rerun <= planned, description
    assert not (planned & change.must_not_rerun), description


def _planned_stage_configs(workdir: Path, config: dict) -> dict[str, set[str]]:
    """Rule -> the --config-json of its planned jobs, for every rule (a forced dry run of ``config``)."""
    write_config(workdir, config)
    output = run_snakemake(workdir, "--dry-run", "--forceall", "--printshellcmds", "--cores", "2", "all")
    return {rule: {option_value(c, "--config-json") for c in commands if "--config-json" in c} for rule, commands in planned_commands(output).items()}


def test_energy_weights_are_not_tracked_by_training_or_post_optimization(tmp_path):
    """Training and post-optimization read one key of `energy` (the self-penetration margin) and get only
    that key: new `energy.weights` change the params of the stages that weigh energies with them
    (optimization from scratch, the evaluation's energies), not those of training or post-optimization, so these rerun
    only when their inputs change."""
    (tmp_path / "meshes").mkdir()
    base = tiny_config(tmp_path / "meshes")
    description, changed = changed_config(base, "energy", "weights.dis")

    before = _planned_stage_configs(tmp_path / "before", base)
    after = _planned_stage_configs(tmp_path / "after", changed)

    assert before["optimize_grasps"] != after["optimize_grasps"] and before["evaluate_simulate"] != after["evaluate_simulate"], description
    for rule in ("train_cvae", "post_optimize"):
        assert before[rule] == after[rule], (description, rule)
        assert all(json.loads(c)["energy"] == {"self_penetration_margin_m": base["energy"]["self_penetration_margin_m"]} for c in after[rule])


@pytest.mark.parametrize(("section", "key", "rule"), RESULT_NEUTRAL_KEYS, ids=lambda name: name)
def test_result_neutral_setting_reruns_nothing(complete_run, scratch_copy, section, key, rule):
    description, config = changed_config(complete_run.config, section, key)
    write_config(scratch_copy, config)

    assert planned_rules(scratch_copy) == set(), description


def test_result_neutral_settings_still_reach_their_stages(tmp_path):
    (tmp_path / "meshes").mkdir()
    neutral_values = {section: {key: 7} for section, key, _ in RESULT_NEUTRAL_KEYS}
    write_config(tmp_path / "run", tiny_config(tmp_path / "meshes", **neutral_values))

    output = run_snakemake(tmp_path / "run", "--dry-run", "--printshellcmds", "--cores", "2", "all")

    commands = planned_commands(output)
    for section, key, rule in RESULT_NEUTRAL_KEYS:
        stage_config = json.loads(option_value(commands[rule][0], "--config-json"))
        assert stage_config[section][key] == 7, f"{section}.{key} does not reach rule {rule}"


def _source_copy(tmp_path: Path) -> Path:
    """A copy of the package source that a test may edit (put first on PYTHONPATH)."""
    source = checkout() / "src" / "dexlite_pipeline"
    target = tmp_path / "src" / "dexlite_pipeline"
    shutil.copytree(source, target, ignore=shutil.ignore_patterns("__pycache__"))
    return target.parent


def _code_closures(graph: dict) -> dict[str, set[str]]:
    """Rule -> every package module its code hash covers (the modules it names and their imports)."""
    root = checkout() / "src" / "dexlite_pipeline"
    return {
        rule: set(module_closure(*modules, root=root))
        for rule, modules in rule_code_modules().items()
        if rule in graph
    }


def _module_file(source: Path, module: str) -> Path:
    relative = module.split(".")[1:]
    path = source.joinpath("dexlite_pipeline", *relative).with_suffix(".py")
    return path if path.is_file() else source.joinpath("dexlite_pipeline", *relative, "__init__.py")


def _append_statement(module_file: Path) -> None:
    module_file.write_text(module_file.read_text() + "\nCODE_CHANGE_PROBE = 1\n")


@pytest.mark.parametrize("stage", ["prepare_objects", "lift_validate", "train_cvae", "post_optimize", "evaluate"])
def test_stage_code_change_reruns_that_stage_and_downstream(complete_run, tmp_path, stage):
    graph = complete_run.graph
    module = f"dexlite_pipeline.stages.{stage}"
    users = {rule for rule, closure in _code_closures(graph).items() if module in closure}
    assert stage in users, f"rule {stage} does not hash its own module"
    source = _source_copy(tmp_path)
    _append_statement(_module_file(source, module))

    planned = planned_rules(complete_run.workdir, env={"PYTHONPATH": str(source)})

    assert planned == downstream(graph, users)


def test_comment_only_change_reruns_nothing(complete_run, tmp_path):
    source = _source_copy(tmp_path)
    stage_file = source / "dexlite_pipeline" / "stages" / "prepare_objects.py"
    stage_file.write_text(stage_file.read_text() + "\n# a comment is not a change of behaviour\n")

    assert planned_rules(complete_run.workdir, env={"PYTHONPATH": str(source)}) == set()


def test_library_change_reruns_the_stages_that_import_it(complete_run, tmp_path):
    """The library module with the fewest dependent stages: exactly those (and downstream) rerun."""
    graph = complete_run.graph
    closures = _code_closures(graph)
    library = {m for closure in closures.values() for m in closure if ".stages" not in m}
    users_of = {m: {rule for rule, closure in closures.items() if m in closure} for m in library}
    module = min(sorted(library), key=lambda m: len(downstream(graph, users_of[m])))
    users = users_of[module]
    if downstream(graph, users) == downstream(graph, set(closures)):
        pytest.skip("every library module reaches every stage")
    source = _source_copy(tmp_path)
    _append_statement(_module_file(source, module))

    planned = planned_rules(complete_run.workdir, env={"PYTHONPATH": str(source)})

    assert planned == downstream(graph, users), module
