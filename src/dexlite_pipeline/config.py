"""Configuration: load ``config.yaml``, validate it against the JSON schema, build typed sections.

Each component owns a small frozen dataclass that maps one-to-one to its section of the
config file (``from_section``); unknown or missing keys fail with a message that names the
file and key. The schema ships in the package so that Snakemake and the CLI validate alike.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import os
import typing
from pathlib import Path
from typing import Any, TypeVar

import yaml

SCHEMA_PATH = Path(__file__).parent / "schemas" / "config.schema.yaml"
# The default config.yaml is package data (installed with the package); the checkout's top-level
# config.yaml, which the workflow reads, is a link to this one file.
DEFAULT_CONFIG_PATH = Path(__file__).parent / "data" / "config.yaml"
# The keys of config section ``objects`` a DexGraspNet import uses (its meshes bring their own
# convex pieces); here, not in io.dexgraspnet, because the workflow reads it while parsing.
IMPORT_ASSET_KEYS = ("sdf_resolution", "sdf_padding", "surface_points")

T = TypeVar("T")


class ConfigError(ValueError):
    """A configuration value that is missing, unknown or of the wrong type."""


def load_schema() -> dict:
    return yaml.safe_load(SCHEMA_PATH.read_text())


JSON_TYPE_NAMES = {
    "array": "a list",
    "object": "a mapping of keys to values",
    "string": "a string",
    "number": "a number",
    "integer": "an integer",
    "boolean": "true or false",
    "null": "null",
}


def _json_type_of(value: Any) -> str:
    """The JSON type name of a parsed value (for 'expected X, got Y' messages)."""
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "number"
    if isinstance(value, str):
        return "string"
    if isinstance(value, (list, tuple)):
        return "array"
    if isinstance(value, dict):
        return "object"
    return "null" if value is None else type(value).__name__


def _type_label(json_type: str) -> str:
    """'a list (array)', 'a number': the plain name, with the schema's word when it differs."""
    name = JSON_TYPE_NAMES.get(json_type, json_type)
    return name if json_type in name else f"{name} ({json_type})"


def _error_line(err, where: str) -> str:
    """One line for a schema violation: where, the dotted key, and what was expected."""
    key = ".".join(str(p) for p in err.absolute_path) or "(top level)"
    if err.validator == "type":
        expected = err.validator_value if isinstance(err.validator_value, list) else [err.validator_value]
        wanted = " or ".join(_type_label(t) for t in expected)
        return f"{where}: {key}: expected {wanted}, got {JSON_TYPE_NAMES.get(_json_type_of(err.instance), 'a value')} {json.dumps(err.instance, default=str)}"
    if err.validator == "additionalProperties":
        allowed = set(err.schema.get("properties", {}))
        unknown = sorted(k for k in err.instance if k not in allowed)
        return f"{where}: {key}: unknown key(s) {', '.join(unknown)} (known: {', '.join(sorted(allowed))})"
    return f"{where}: {key}: {err.message}"


def schema_errors(config: dict, where: str, partial: bool = False) -> list[str]:
    """Every schema violation of ``config`` as one line each, in key order.

    ``partial``: ``config`` holds only some sections and keys (a stage's ``--config-json``),
    so missing ('required') keys are not errors; types, ranges and unknown keys still are.
    """
    import jsonschema

    validator = jsonschema.Draft202012Validator(load_schema())
    errors = sorted(validator.iter_errors(config), key=lambda e: [str(p) for p in e.absolute_path])
    return [_error_line(e, where) for e in errors if not (partial and e.validator == "required")]


def validate_config(config: dict, where: str = "config", partial: bool = False) -> dict:
    """Validate ``config`` against the schema; raise ConfigError naming the key and what was expected."""
    errors = schema_errors(config, where, partial)
    if errors:
        raise ConfigError(errors[0])
    return config


def load_config(path: str | os.PathLike) -> dict:
    """Read and validate a config file."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{p}: config file not found")
    try:
        config = yaml.safe_load(p.read_text()) or {}
    except yaml.YAMLError as exc:
        raise ConfigError(f"{p}: not valid YAML: {exc}") from exc
    return validate_config(config, str(p))


def default_config() -> dict:
    """The package's default ``config.yaml``, validated."""
    return load_config(DEFAULT_CONFIG_PATH)


def merge_config(base: dict, overlay: dict) -> dict:
    """``overlay`` over ``base`` as Snakemake merges ``--configfile``s: nested mappings merged key by
    key, anything else replaced. Returns a new mapping; neither argument is changed or shared."""
    out = copy.deepcopy(base)
    for key, value in overlay.items():
        out[key] = merge_config(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else copy.deepcopy(value)
    return out


def from_section(cls: type[T], section: dict[str, Any] | None, where: str) -> T:
    """Build dataclass ``cls`` from a config mapping: unknown keys are errors, missing keys take defaults."""
    section = dict(section or {})
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(section) - set(fields))
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(unknown)}")
    hints = typing.get_type_hints(cls)
    values = {}
    for name, value in section.items():
        hint = hints[name]
        _check_type(value, hint, f"{where}.{name}")
        if dataclasses.is_dataclass(hint) and isinstance(value, dict):
            value = from_section(hint, value, f"{where}.{name}")
        elif typing.get_origin(hint) is tuple and isinstance(value, list):
            value = tuple(value)
        values[name] = value
    try:
        return cls(**values)
    except TypeError as exc:
        raise ConfigError(f"{where}: {exc}") from exc


def _check_type(value: Any, hint: Any, key: str) -> None:
    """ConfigError naming ``key`` when ``value`` cannot be a field of type ``hint`` (plain types only).

    Covers callers that build sections without the schema (library use, CLI overrides):
    numbers for float fields (bool excluded), whole numbers for int fields, true/false for
    bool, text for str, lists for tuples and mappings for nested sections. Other hints
    (unions, Literal) are left to the dataclass.
    """
    import numbers

    import numpy as np

    checks = {
        float: ("number", lambda v: isinstance(v, numbers.Real) and not isinstance(v, bool)),
        int: ("integer", lambda v: isinstance(v, numbers.Integral) and not isinstance(v, bool)),
        bool: ("boolean", lambda v: isinstance(v, (bool, np.bool_))),
        str: ("string", lambda v: isinstance(v, str)),
    }
    if hint in checks:
        expected, ok = checks[hint]
    elif typing.get_origin(hint) is tuple:
        expected, ok = "array", lambda v: isinstance(v, (list, tuple))
    elif dataclasses.is_dataclass(hint):
        expected, ok = "object", lambda v: isinstance(v, dict) or isinstance(v, hint)
    else:
        return
    if not ok(value):
        shown = json.dumps(value, default=str)
        raise ConfigError(f"{key}: expected {_type_label(expected)}, got {JSON_TYPE_NAMES.get(_json_type_of(value), 'a value')} {shown}")


def config_subset(config: dict, *names: str) -> dict:
    """The named sections of ``config``; a dotted name (``energy.self_penetration_margin_m``) takes one key of a section."""
    subset: dict = {}
    for name in names:
        section, _, key = name.partition(".")
        if not key:
            subset[section] = config.get(section)
        elif isinstance(config.get(section), dict) and key in config[section]:
            subset.setdefault(section, {})[key] = config[section][key]
    return subset


def section_json(config: dict, *names: str) -> str:
    """The named sections (or dotted keys, ``config_subset``) as canonical JSON (sorted keys): a rule's ``params`` value."""
    return json.dumps(config_subset(config, *names), sort_keys=True, separators=(",", ":"))


CONFIG_FILE_SUFFIXES = (".json", ".yaml", ".yml")


def parse_config_json(text: str, option: str = "--config-json") -> dict:
    """Config sections from inline JSON or from a .json / .yaml file, checked against the schema.

    ``text`` is JSON when it starts with ``{`` (or ``[``); otherwise it is the path of a file (JSON, or
    YAML for .yaml / .yml). The sections may be partial (any subset of sections and keys), but
    every value given must have the schema's type and range, and every key must exist.
    """
    stripped = text.strip()
    where = option
    if stripped[:1] in ("{", "[") or not stripped:
        value = _parse_json(stripped or "{}", option)
    else:
        path = Path(stripped).expanduser()
        where = f"{option} {stripped}"
        if not path.is_file():
            raise ConfigError(f"{where}: no such file (give inline JSON such as '{{\"lift\": {{...}}}}' or a .json/.yaml file)")
        content = path.read_text()
        if path.suffix.lower() in (".yaml", ".yml"):
            try:
                value = yaml.safe_load(content) or {}
            except yaml.YAMLError as exc:
                raise ConfigError(f"{where}: not valid YAML: {exc}") from exc
        else:
            value = _parse_json(content, where)
    if not isinstance(value, dict):
        raise ConfigError(f"{where}: expected a mapping of config sections, got {JSON_TYPE_NAMES.get(_json_type_of(value), 'a value')}")
    return validate_config(value, where, partial=True)


def _parse_json(text: str, where: str):
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{where}: not valid JSON: {exc}") from exc


def json_ready(value: Any, nan_as_none: bool = False) -> Any:
    """A settings object (dataclass), mapping or value as plain JSON values, recursively: dataclasses
    as dicts, tuples as lists, numpy scalars unwrapped, and with ``nan_as_none`` NaN as null (what a
    stage records of its config and results in its outputs' attributes)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        value = dataclasses.asdict(value)
    if isinstance(value, dict):
        return {str(k): json_ready(v, nan_as_none) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v, nan_as_none) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        value = value.item()
    if nan_as_none and isinstance(value, float) and value != value:
        return None
    return value
