"""Configuration: load ``config.yaml``, validate it against the JSON schema, build typed sections.

Each component owns a small frozen dataclass that maps one-to-one to its section of the
config file (``from_section``); unknown or missing keys fail with a message that names the
file and key. The schema ships in the package so that Snakemake and the CLI validate alike.
"""

from __future__ import annotations

import dataclasses
import json
import os
import typing
from pathlib import Path
from typing import Any, TypeVar

import yaml

SCHEMA_PATH = Path(__file__).parent / "schemas" / "config.schema.yaml"

T = TypeVar("T")


class ConfigError(ValueError):
    """A configuration value that is missing, unknown or of the wrong type."""


def load_schema() -> dict:
    return yaml.safe_load(SCHEMA_PATH.read_text())


def validate_config(config: dict, where: str = "config") -> dict:
    """Validate ``config`` against the schema; raise ConfigError with a one-line reason."""
    import jsonschema

    validator = jsonschema.Draft202012Validator(load_schema())
    errors = sorted(validator.iter_errors(config), key=lambda e: list(e.absolute_path))
    if errors:
        err = errors[0]
        key = ".".join(str(p) for p in err.absolute_path) or "(top level)"
        raise ConfigError(f"{where}: {key}: {err.message}")
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
        if dataclasses.is_dataclass(hint) and isinstance(value, dict):
            value = from_section(hint, value, f"{where}.{name}")
        elif typing.get_origin(hint) is tuple and isinstance(value, list):
            value = tuple(value)
        values[name] = value
    try:
        return cls(**values)
    except TypeError as exc:
        raise ConfigError(f"{where}: {exc}") from exc


def section_json(config: dict, *names: str) -> str:
    """The named sections as canonical JSON (sorted keys): a rule's ``params`` value."""
    return json.dumps({n: config.get(n) for n in names}, sort_keys=True, separators=(",", ":"))


def parse_config_json(text: str) -> dict:
    """Inverse of ``section_json``, with a clear error for malformed input."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"--config-json: not valid JSON: {exc}") from exc
    if not isinstance(value, dict):
        raise ConfigError("--config-json: expected a JSON object of config sections")
    return value
