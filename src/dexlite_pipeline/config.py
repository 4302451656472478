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


@dataclasses.dataclass(frozen=True)
class RetiredKey:
    """A config key that no longer exists: the dotted path of the key that took its place (None: nothing
    did) and, in one line, what a user of an old config needs to know to move its value."""

    replacement: str | None
    note: str


_SPACING_NOTE = ("a count of E_pen's object points per object became their mean spacing in metres at the grasp's scale: "
                 "do not copy the number, config.yaml has the default")
_ANNEALING_KEYS = ("contact_switch_probability", "iterations", "rmsprop_eps", "rmsprop_mu", "starting_temperature", "step_size",
                   "step_size_decay", "step_size_period", "temperature_decay", "temperature_period")  # fmt: skip
_WEIGHT_KEYS = ("dis", "fc", "joints", "pen", "spen")
_THRESHOLD_KEYS = ("max_e_dis_m", "max_e_fc", "max_e_pen_m")

# Every config key that was renamed or removed, by its old dotted path: a config that still has one fails
# with where its value goes now (``retired_keys_message``), not with a bare unknown-key error of the schema.
RETIRED_KEYS: dict[str, RetiredKey] = {
    "seed_grasps": RetiredKey("optimize_grasps", 'the grasp optimization from scratch; "seed" means a random seed only; same keys'),
    **{f"seed_grasps.annealing.{key}": RetiredKey(f"optimize_grasps.{key}", "a setting of the optimization, not of the annealing "
                                                                          "schedule it shares with post_optimize")
       for key in ("contact_search_every", "final_contact_samples", "keep_best", "trace_every")},
    **{f"seed_grasps.thresholds.{key.replace('max_e', 'max_E')}": RetiredKey(f"optimize_grasps.thresholds.{key}", "threshold names are lower case")
       for key in _THRESHOLD_KEYS},
    **{f"curate.{key}": RetiredKey(f"curate.thresholds.{key}", "the thresholds are one mapping, as optimize_grasps.thresholds")
       for key in _THRESHOLD_KEYS},
    **{f"post_optimize.{key}": RetiredKey(f"post_optimize.annealing.{key}", "the annealing schedule is one mapping, as optimize_grasps.annealing")
       for key in _ANNEALING_KEYS},
    **{f"{section}.weight_{key}": RetiredKey(f"{section}.energy_weights.{key}", "the energy weights are one mapping, as energy.weights")
       for section in ("train", "post_optimize") for key in _WEIGHT_KEYS},
    "energy.object_points": RetiredKey("energy.object_point_spacing_m", _SPACING_NOTE),
    "post_optimize.energy_object_points": RetiredKey("post_optimize.energy_point_spacing_m", _SPACING_NOTE),
    "train.energy_object_points": RetiredKey("train.energy_point_spacing_m", _SPACING_NOTE),
    "lift.penetration_point_spacing_m": RetiredKey(None, "the start-depth check of the lift test always samples the object surface 2 mm apart"),
    "stability.time_step_s": RetiredKey("stability.timestep_s", "one spelling of the physics step in seconds, as lift.timestep_s"),
    "train.model.translation_from_point": RetiredKey("train.model.pose_frame", "true is pose_frame: point, false is pose_frame: object"),
    "evaluate.seed_protocol": RetiredKey("evaluate.writeup_protocol", "the DexLite write-up's lenient lift test; \"seed\" means a random "
                                                                      "seed only; same keys"),
    "evaluate.seed_passing_only": RetiredKey(None, "every method is counted over all its attempts, and after evaluate.filter_thresholds "
                                                   "in the filtered_* columns"),
}  # fmt: skip


def _retired_key(path: str) -> RetiredKey | None:
    """The ``RETIRED_KEYS`` entry of dotted ``path``, also when its section is spelled with the new name
    (``optimize_grasps.annealing.keep_best`` is ``seed_grasps.annealing.keep_best``)."""
    if path in RETIRED_KEYS:
        return RETIRED_KEYS[path]
    for old, entry in RETIRED_KEYS.items():
        new = entry.replacement
        if new and path.startswith(new + ".") and (moved := RETIRED_KEYS.get(old + path[len(new):])):
            return moved
    return None


def _dotted_paths(mapping: dict, prefix: str = ""):
    """Every key of a nested mapping as a dotted path, each section before its keys."""
    for key, value in mapping.items():
        path = f"{prefix}{key}"
        yield path
        if isinstance(value, dict):
            yield from _dotted_paths(value, f"{path}.")


def retired_keys_message(config: dict) -> str:
    """One line naming every renamed or removed key (``RETIRED_KEYS``) in ``config`` and where its value goes;
    "" when there is none."""
    hints = []
    for path in _dotted_paths(config):
        if entry := _retired_key(path):
            outcome = f"was renamed {entry.replacement}" if entry.replacement else "was removed"
            hints.append(f"config key {path} {outcome} ({entry.note})")
    return "; ".join(hints)


def validate_config(config: dict, where: str = "config", partial: bool = False) -> dict:
    """Validate ``config`` against the schema; raise ConfigError naming the key and what was expected
    (for a renamed or removed key: its replacement, ``retired_keys_message``)."""
    if retired := retired_keys_message(config):
        raise ConfigError(f"{where}: {retired}")
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


# JSON-schema keywords ``setting`` takes, by their Python spelling.
_SCHEMA_KEYWORDS = {
    "minimum": "minimum", "maximum": "maximum", "exclusive_minimum": "exclusiveMinimum", "exclusive_maximum": "exclusiveMaximum",
    "enum": "enum", "pattern": "pattern", "min_items": "minItems", "max_items": "maxItems", "unique_items": "uniqueItems",
    "items": "items",
}  # fmt: skip


def setting(default: Any = dataclasses.MISSING, doc: str = "", *, factory: Any = None, required: bool = False,
            result_neutral: bool = False, rules: tuple[str, ...] = (), docs: dict[str, str] | None = None, **schema: Any) -> Any:
    """A config key: a dataclass field with its default and everything else the key needs, in one place.

    ``doc`` is the key's comment in the default config.yaml (units, why), ``schema`` its JSON-schema
    constraints beyond the type its annotation gives (``minimum``, ``exclusive_minimum``, ``maximum``,
    ``enum``, ``pattern``, ``min_items``, ``unique_items``, ``items``: constraints of a list's items);
    ``required``: the schema requires the key in a whole config. ``result_neutral``: changing the value
    cannot change any output, so the workflow passes it to the stage without rerunning it (common.smk's
    RESULT_NEUTRAL_KEYS). ``rules``: for a section whose rules take it key by key (``loop``, ``evaluate``),
    the rules that pass this key to their stage (``rule_keys``). A nested section (``factory`` its class)
    may document its keys for this place in ``docs`` (key -> comment; the class's own docs elsewhere).
    ``config_files`` writes the schema and config.yaml from these fields: docs/design.md, "Adding a config key".
    """
    unknown = sorted(set(schema) - set(_SCHEMA_KEYWORDS))
    if unknown:
        raise TypeError(f"setting(): unknown schema keyword(s) {', '.join(unknown)} (known: {', '.join(_SCHEMA_KEYWORDS)})")
    metadata = {
        "doc": doc.strip(), "required": required, "result_neutral": result_neutral, "rules": tuple(rules), "docs": dict(docs or {}),
        "schema": _schema_keywords(schema),
    }  # fmt: skip
    if factory is not None:
        return dataclasses.field(default_factory=factory, metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def _schema_keywords(schema: dict) -> dict:
    """``setting``'s schema keywords in JSON-schema spelling, tuples as lists (``items`` too)."""
    return {_SCHEMA_KEYWORDS.get(key, key): _schema_keywords(value) if isinstance(value, dict) else list(value) if isinstance(value, tuple)
            else value for key, value in schema.items()}  # fmt: skip


def setting_fields(cls: type) -> list[dataclasses.Field]:
    """The fields of settings class ``cls`` in config.yaml's order: its own first, then those it inherits."""
    own = cls.__dict__.get("__annotations__", {})
    fields = dataclasses.fields(cls)
    return [f for f in fields if f.name in own] + [f for f in fields if f.name not in own]


def rule_keys(cls: type, rule: str) -> tuple[str, ...]:
    """The keys of settings class ``cls`` whose ``setting(rules=...)`` names ``rule``, in field order."""
    return tuple(f.name for f in setting_fields(cls) if rule in f.metadata.get("rules", ()))


def result_neutral_keys(cls: type) -> dict[str, tuple[str, ...]]:
    """Section -> its keys marked ``setting(result_neutral=True)``, for every section of the config tree ``cls``."""
    hints = typing.get_type_hints(cls)
    neutral = {}
    for f in setting_fields(cls):
        if dataclasses.is_dataclass(hints[f.name]):
            keys = tuple(g.name for g in setting_fields(hints[f.name]) if g.metadata.get("result_neutral"))
            if keys:
                neutral[f.name] = keys
    return neutral


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
