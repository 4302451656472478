"""config.yaml, its JSON schema and the typed settings classes stay in step; the profiles validate.

The settings classes are the source: config.yaml and the schema are generated from them (``config_files``).
"""

from __future__ import annotations

import json
import dataclasses
import typing
from pathlib import Path

import pytest
import yaml

from dexlite_pipeline.config import (
    RETIRED_KEYS, ConfigError, from_section, load_config, load_schema, merge_config, retired_keys_message, validate_config,
)  # fmt: skip
from dexlite_pipeline.settings import PipelineConfig, build_config

ROOT = Path(__file__).resolve().parents[1]
# section name -> its settings class, as the root of the typed tree holds them
SECTIONS = {name: hint for name, hint in typing.get_type_hints(PipelineConfig).items() if dataclasses.is_dataclass(hint)}


def _field_tree(cls) -> dict:
    """Field names of a settings class, nested settings classes as sub-trees."""
    hints = typing.get_type_hints(cls)
    return {f.name: _field_tree(hints[f.name]) if dataclasses.is_dataclass(hints[f.name]) else None for f in dataclasses.fields(cls)}


def _key_tree(section: dict, like: dict) -> dict:
    """Keys of a config section, descending where the settings class nests a class."""
    return {k: _key_tree(v, like[k]) if isinstance(like.get(k), dict) and isinstance(v, dict) else None for k, v in section.items()}


@pytest.fixture(scope="module")
def config() -> dict:
    return load_config(ROOT / "config.yaml")


def test_the_schema_and_the_default_config_are_generated_from_the_settings_classes():
    """Both files are what ``config_files`` writes from the settings classes' fields (docs/design.md, "Adding a config key")."""
    from dexlite_pipeline.config_files import REWRITE_COMMAND, generated_files

    stale = [str(path.relative_to(ROOT / "src")) for path, text in generated_files().items() if path.read_text() != text]
    assert not stale, f"stale: {', '.join(stale)}; rewrite them with `PYTHONPATH=src .venv/bin/{REWRITE_COMMAND}`"


def _leaf_settings(cls, prefix: str = ""):
    """(dotted key, field) of every key below settings class ``cls`` that is not itself a section."""
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        if dataclasses.is_dataclass(hints[f.name]):
            yield from _leaf_settings(hints[f.name], f"{prefix}{f.name}.")
        else:
            yield f"{prefix}{f.name}", f


def test_every_key_is_a_documented_setting():
    """Each key of the tree is a ``config.setting`` field with a comment (what config.yaml says about it)."""
    undocumented = [key for key, f in _leaf_settings(PipelineConfig) if not f.metadata.get("doc")]
    assert not undocumented, f"keys without setting(doc=...): {', '.join(undocumented)}"


def test_result_neutral_keys_and_rule_keys_come_from_the_settings():
    """The workflow's untracked keys (common.smk) and the keys each loop and evaluation rule passes are marked on the fields."""
    from dexlite_pipeline.config import result_neutral_keys
    from dexlite_pipeline.evaluation.step_keys import AGGREGATE_KEYS, REPORT_KEYS, SIMULATE_KEYS
    from dexlite_pipeline.loop.config import loop_rule_sections

    assert result_neutral_keys(PipelineConfig) == {
        "curate": ("energy_batch_size",), "evaluate": ("energy_batch_size",), "optimize_grasps": ("progress_every",)}
    assert set(SIMULATE_KEYS) == {"methods", "splits", "grasps_per_object", "ladder_grasps_per_object", "six_directions",
                                  "energy_batch_size", "writeup_protocol"}  # fmt: skip
    assert set(AGGREGATE_KEYS) == {"methods", "splits", "entropy_bins", "pca_components", "filter_thresholds"}
    assert REPORT_KEYS == ("rendered_per_method",)
    assert loop_rule_sections("loop_post_optimize") == (
        "seed", "device", "post_optimize", "scene", "energy.self_penetration_margin_m", "loop.post_iterations")


def test_the_config_tree_imports_without_numpy():
    """The workflow imports the settings classes while it parses (common.smk): standard library and PyYAML only."""
    import subprocess
    import sys

    code = "import sys, dexlite_pipeline.settings, dexlite_pipeline.evaluation.step_keys; print(sorted({'numpy', 'torch', 'jsonschema'} & set(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip() == "[]"


def test_config_has_exactly_the_sections_the_code_reads(config):
    assert set(config) - {"seed", "device", "shards", "hand"} == set(SECTIONS)


@pytest.mark.parametrize("name", sorted(SECTIONS))
def test_every_setting_is_in_config_yaml_and_builds(config, name):
    """Each section lists every field of its class (so the file documents them all) and nothing else."""
    fields = _field_tree(SECTIONS[name])
    assert _key_tree(config[name], fields) == fields
    from_section(SECTIONS[name], config[name], f"config.{name}")


def _schema_tree(schema: dict, root: dict) -> dict | None:
    """Property names of an object schema (``$ref`` to ``#/$defs/...`` followed), nested object schemas as sub-trees."""
    if "$ref" in schema:
        schema = root["$defs"][schema["$ref"].removeprefix("#/$defs/")]
    if schema.get("type") != "object" or "properties" not in schema:
        return None
    return {k: _schema_tree(v, root) for k, v in schema["properties"].items()}


def _json_ready(value):
    """A settings tree as the mapping config.yaml would spell it (tuples as lists)."""
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    return value


def test_schema_describes_exactly_the_keys_of_config_yaml(config):
    schema = load_schema()
    tree = _schema_tree(schema, schema)
    assert _key_tree(config, tree) == tree


def test_defaults_schema_and_config_yaml_agree(config):
    """One set of defaults: the settings classes' defaults are config.yaml's values, key for key,
    and they satisfy the schema (types and ranges); the whole file builds the same typed tree."""
    defaults = PipelineConfig()
    assert build_config(config) == defaults
    as_mapping = _json_ready(dataclasses.asdict(defaults))
    assert as_mapping == config
    validate_config(as_mapping, "settings defaults")


def test_a_shared_shape_is_one_type_wherever_it_appears():
    from dexlite_pipeline.energy.config import EnergyWeights
    from dexlite_pipeline.energy.config import EnergyThresholds
    from dexlite_pipeline.optim.config import AnnealingSchedule
    from dexlite_pipeline.optim.config import InitConfig

    hints = {name: typing.get_type_hints(cls) for name, cls in SECTIONS.items()}
    assert hints["energy"]["weights"] is hints["train"]["energy_weights"] is hints["post_optimize"]["energy_weights"] is EnergyWeights
    assert hints["optimize_grasps"]["annealing"] is hints["post_optimize"]["annealing"] is AnnealingSchedule
    assert hints["optimize_grasps"]["thresholds"] is hints["curate"]["thresholds"] is EnergyThresholds
    assert hints["optimize_grasps"]["init"] is hints["post_optimize"]["random_init"] is InitConfig


def test_the_coacd_settings_are_one_type_with_one_set_of_defaults():
    """Section objects and the asset build settings take their coacd_* fields, defaults included, from CoacdSettings."""
    from dexlite_pipeline.objects.config import AssetBuildSettings, CoacdSettings, ObjectsConfig

    coacd = {f.name: f.default for f in dataclasses.fields(CoacdSettings)}
    for cls in (ObjectsConfig, AssetBuildSettings):
        assert issubclass(cls, CoacdSettings) and {f.name: f.default for f in dataclasses.fields(cls) if f.name.startswith("coacd_")} == coacd


@pytest.mark.parametrize("profile", sorted(p.name for p in (ROOT / "config" / "profiles").glob("*.yaml")))
def test_profiles_over_the_default_config_validate_and_build(config, profile):
    merged = merge_config(config, yaml.safe_load((ROOT / "config" / "profiles" / profile).read_text()))
    validate_config(merged, profile)
    build_config(merged, profile)


def test_schema_rejects_unknown_keys_and_wrong_types(config):
    unknown = merge_config(config, {"post_optimize": {"annealing": {"iteratons": 100}}})
    with pytest.raises(ConfigError, match="post_optimize"):
        validate_config(unknown)
    wrong_type = merge_config(config, {"lift": {"friction": "high"}})
    with pytest.raises(ConfigError, match="lift.friction"):
        validate_config(wrong_type)


def test_a_string_where_a_list_is_expected_is_one_clear_error(tmp_path, capsys):
    from dexlite_pipeline.cli import main

    cfg = json.dumps({"objects": {"builtin_count": 0, "mesh_dirs": str(tmp_path)}})
    assert main(["prepare-objects", "--config-json", cfg, "--catalog", str(tmp_path / "out" / "catalog.parquet"), "--record", str(tmp_path / "out" / "prepare_config.json")]) == 2
    error = capsys.readouterr().err.strip()
    assert error == f'dexlite prepare-objects: error: --config-json: objects.mesh_dirs: expected a list (array), got a string "{tmp_path}"'
    assert not (tmp_path / "out").exists()


def _dotted(tree: dict, prefix: str = "") -> set[str]:
    """Every key of a key tree (``_schema_tree``) as a dotted path."""
    return {path for key, sub in tree.items() for path in {f"{prefix}{key}"} | (_dotted(sub, f"{prefix}{key}.") if sub else set())}


def test_every_retired_key_is_gone_and_its_replacement_exists(config):
    """The hints name keys the schema no longer has and replacements it has; no key of config.yaml gets a hint."""
    schema = load_schema()
    keys = _dotted(_schema_tree(schema, schema))
    assert not set(RETIRED_KEYS) & keys
    assert {entry.replacement for entry in RETIRED_KEYS.values()} - {None} <= keys
    assert retired_keys_message(config) == ""


@pytest.mark.parametrize(
    "old, hint",
    [
        ({"seed_grasps": {"grasps_per_object": 8}}, "config key seed_grasps was renamed optimize_grasps ("),
        ({"energy": {"object_points": 2000}}, "config key energy.object_points was renamed energy.object_point_spacing_m (a count of E_pen's "
                                              "object points per object became their mean spacing in metres"),
        ({"evaluate": {"seed_protocol": {"enabled": True}}}, "config key evaluate.seed_protocol was renamed evaluate.writeup_protocol ("),
        ({"lift": {"penetration_point_spacing_m": 0.002}}, "config key lift.penetration_point_spacing_m was removed ("),
        # a key that moved out of a renamed section, with the section's new name already in place
        ({"optimize_grasps": {"annealing": {"keep_best": True}}}, "config key optimize_grasps.annealing.keep_best was renamed optimize_grasps.keep_best ("),
    ],
)  # fmt: skip
def test_an_old_key_fails_naming_its_replacement(config, tmp_path, old, hint):
    path = tmp_path / "old.yaml"
    path.write_text(yaml.safe_dump(merge_config(config, old)))
    with pytest.raises(ConfigError) as error:
        load_config(path)
    assert str(error.value).startswith(f"{path}: {hint}") and "\n" not in str(error.value)


def test_a_stage_given_an_old_key_names_its_replacement(tmp_path, capsys):
    from dexlite_pipeline.cli import main

    cfg = json.dumps({"seed": 0, "objects": {"builtin_count": 0}, "energy": {"object_points": 2000}})
    out = tmp_path / "out"
    assert main(["prepare-objects", "--config-json", cfg, "--catalog", str(out / "catalog.parquet"), "--record", str(out / "prepare_config.json")]) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith("dexlite prepare-objects: error: --config-json: config key energy.object_points was renamed energy.object_point_spacing_m (")
    assert not out.exists()


def test_library_sections_check_types_without_the_schema():
    from dexlite_pipeline.sim.config import LiftConfig

    with pytest.raises(ConfigError, match=r'^config.lift.friction: expected a number, got a string "abc"$'):
        from_section(LiftConfig, {"friction": "abc"}, "config.lift")
    assert from_section(LiftConfig, {"friction": 1}, "config.lift").friction == 1


def test_the_workflow_config_and_the_package_default_are_one_file():
    """config.yaml at the top (the workflow's) links to the package's default config: one source of truth."""
    from dexlite_pipeline.config import DEFAULT_CONFIG_PATH, default_config

    assert (ROOT / "config.yaml").is_symlink(), "config.yaml must link to src/dexlite_pipeline/data/config.yaml"
    assert (ROOT / "config.yaml").resolve() == DEFAULT_CONFIG_PATH.resolve()
    assert default_config() == load_config(ROOT / "config.yaml")


def test_the_shipped_model_path_in_the_config_is_the_package_data_file(config):
    """sample.shipped_model (a path in this checkout, for the workflow) names the packaged model file."""
    from dexlite_pipeline.model.shipped import SHIPPED_MODEL_PATH, SHIPPED_MODEL_RELATIVE

    assert config["sample"]["shipped_model"] == str(SHIPPED_MODEL_RELATIVE)
    assert (ROOT / SHIPPED_MODEL_RELATIVE).resolve() == SHIPPED_MODEL_PATH.resolve() and SHIPPED_MODEL_PATH.is_file()
