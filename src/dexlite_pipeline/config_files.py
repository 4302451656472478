"""The config files written from the settings classes: the JSON schema and the documented default ``config.yaml``.

Every config key is one field of a settings class (``config.setting``: default, comment, schema constraints);
this module writes the two files that repeat them, and ``tests/test_config.py`` fails when either is stale::

    python -m dexlite_pipeline.config_files           # names each stale file (exit 1)
    python -m dexlite_pipeline.config_files --write   # rewrites them

Types come from the annotations (int, float, bool, str, tuple, a nested settings class); a settings class used in
several places is one ``$defs`` entry of the schema. docs/design.md, "Adding a config key".
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import re
import sys
import textwrap
import typing
from decimal import Decimal
from pathlib import Path

import yaml

from dexlite_pipeline.config import DEFAULT_CONFIG_PATH, SCHEMA_PATH, json_ready, setting_fields
from dexlite_pipeline.settings import PipelineConfig

REWRITE_COMMAND = "python -m dexlite_pipeline.config_files --write"
WIDTH = 130  # longest line of the written files, comments included (a longer value is not broken)
COMMENT_COLUMN = 29  # where a key's comment starts, and its continuation lines
TOP_COMMENT_COLUMN = 21  # the same for the top-level scalar keys (seed, device, shards)
GENERATED_NOTE = (f"Generated from the settings classes (config.setting fields) by `{REWRITE_COMMAND}`:",
                  'edit those, not this file (docs/design.md, "Adding a config key").')
CONFIG_HEADER = (
    "DexLite pipeline configuration. Validated against src/dexlite_pipeline/schemas/config.schema.yaml.",
    "Each stage receives only its own sections (through the rule's params), so changing a",
    "value reruns exactly the stages that use it and what depends on them. Other values for a run:",
    "a file given with --configfile, merged over this one (README, \"Configuration\").",
    *GENERATED_NOTE,
)
SCHEMA_DESCRIPTION = "DexLite pipeline configuration (config.yaml)"
JSON_TYPES = {bool: "boolean", int: "integer", float: "number", str: "string"}
PLAIN_STRING = re.compile(r"^[A-Za-z_$][\w./$-]*$")


# --- the schema


def _nested(hint) -> bool:
    return dataclasses.is_dataclass(hint) and isinstance(hint, type)


def _usages(cls: type, path: str = "") -> dict[type, list[str]]:
    """Settings class -> the dotted keys it is the value of, below ``cls`` (top-level sections excluded)."""
    found: dict[type, list[str]] = {}
    hints = typing.get_type_hints(cls)
    for f in setting_fields(cls):
        if _nested(hints[f.name]):
            key = f"{path}{f.name}"
            if path:
                found.setdefault(hints[f.name], []).append(key)
            for nested, keys in _usages(hints[f.name], f"{key}.").items():
                found.setdefault(nested, []).extend(keys)
    return found


def _def_name(cls: type) -> str:
    """``EnergyWeights`` -> ``energy_weights``: a shared class's name in the schema's ``$defs``."""
    return re.sub(r"(?<!^)(?=[A-Z])", "_", cls.__name__).lower()


def _type_schema(hint) -> dict:
    """The JSON schema of a field's annotation: a plain type or a tuple of one (``tuple[X, ...]``, ``tuple[X, X]``)."""
    if hint in JSON_TYPES:
        return {"type": JSON_TYPES[hint]}
    if typing.get_origin(hint) is tuple:
        args = typing.get_args(hint)
        schema = {"type": "array", "items": _type_schema(args[0])}
        if args[-1] is not Ellipsis:
            schema.update(minItems=len(args), maxItems=len(args))
        return schema
    raise TypeError(f"config_files: no schema for annotation {hint!r} (int, float, bool, str, tuples of them, settings classes)")


def _field_schema(hint, f: dataclasses.Field, shared: set[type]) -> dict:
    if _nested(hint):
        return {"$ref": f"#/$defs/{_def_name(hint)}"} if hint in shared else _object_schema(hint, shared)
    constraints = dict(f.metadata.get("schema", {}))
    schema = _type_schema(hint)
    if "items" in constraints:
        items = {**schema["items"], **constraints.pop("items")}
        schema["items"] = {"enum": items["enum"]} if "enum" in items else items
    schema.update(constraints)
    return {"enum": schema["enum"]} if "enum" in schema else schema


def _object_schema(cls: type, shared: set[type]) -> dict:
    hints = typing.get_type_hints(cls)
    fields = setting_fields(cls)
    schema: dict = {"type": "object", "additionalProperties": False}
    required = [f.name for f in fields if f.metadata.get("required")]
    if required:
        schema["required"] = required
    schema["properties"] = {f.name: _field_schema(hints[f.name], f, shared) for f in fields}
    return schema


def config_schema() -> dict:
    """The JSON schema of config.yaml, from ``PipelineConfig``."""
    usages = _usages(PipelineConfig)
    shared = {cls for cls, keys in usages.items() if len(keys) > 1}
    schema = {"$schema": "https://json-schema.org/draft/2020-12/schema", "description": SCHEMA_DESCRIPTION,
              **_object_schema(PipelineConfig, shared)}  # fmt: skip
    schema["$defs"] = {_def_name(cls): _object_schema(cls, shared) for cls in sorted(shared, key=lambda c: usages[c][0])}
    return schema


# --- YAML text


def _float_text(value: float) -> str:
    """A float as YAML 1.1 (PyYAML) reads back as the same float: ``0.00001``, ``1.0e-8``, never ``1e-05`` (a string there)."""
    text = repr(value)
    if "e" not in text:
        return text
    mantissa, exponent = text.split("e")
    if int(exponent) >= -5:
        return format(Decimal(text), "f")
    return f"{mantissa if '.' in mantissa else mantissa + '.0'}e{int(exponent):+d}".replace("e+-", "e-")


def scalar_text(value) -> str:
    """One value as YAML flow text (a string plain when that reads back as itself, else double-quoted)."""
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return _float_text(value)
    if isinstance(value, str):
        return value if PLAIN_STRING.match(value) and yaml.safe_load(value) == value else json.dumps(value, ensure_ascii=False)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(scalar_text(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{scalar_text(k)}: {scalar_text(v)}" for k, v in value.items()) + "}"
    raise TypeError(f"config_files: cannot write {value!r}")


def _flow_lines(prefix: str, items: list) -> list[str]:
    """``prefix`` and a flow list, broken after a comma where a line would pass ``WIDTH`` (items aligned after the ``[``)."""
    lines, line = [], f"{prefix}["
    indent = " " * len(line)
    for i, item in enumerate(items):
        text = scalar_text(item) + ("," if i < len(items) - 1 else "]")
        if len(line) + len(text) + 1 > WIDTH and not line.endswith("["):
            lines.append(line.rstrip())
            line = indent
        line += text + ("" if i == len(items) - 1 else " ")
    return [*lines, line] if items else [f"{prefix}[]"]


def _commented(lines: list[str], doc: str, column: int) -> list[str]:
    """``lines`` (a key and its value) with comment ``doc`` after the last, wrapped at ``WIDTH``, continued at ``column``."""
    if not doc:
        return lines
    last = lines[-1]
    start = max(column, len(last) + 2)
    wrapper = dict(width=WIDTH, subsequent_indent=" " * column + "# ", break_long_words=False, break_on_hyphens=False)
    if start > WIDTH - 30 or len(lines) > 1:  # no room beside the value, or a value of several lines: the comment below it
        return [*lines, *textwrap.wrap(doc, initial_indent=" " * column + "# ", **wrapper)]
    wrapped = textwrap.wrap(doc, initial_indent=" " * start + "# ", **wrapper)
    return [*lines[:-1], last.ljust(start) + wrapped[0][start:], *wrapped[1:]]


def _mapping_lines(cls: type, values, indent: int, docs: dict[str, str]) -> list[str]:
    """The keys of settings ``values`` (an instance of ``cls``) with their comments; nested sections below their key."""
    hints = typing.get_type_hints(cls)
    lines = []
    for f in setting_fields(cls):
        value, doc = getattr(values, f.name), docs.get(f.name, f.metadata.get("doc", ""))
        column = TOP_COMMENT_COLUMN if indent == 0 and not _nested(hints[f.name]) else COMMENT_COLUMN
        key = " " * indent + f"{f.name}:"
        if _nested(hints[f.name]):
            if indent == 0:
                lines.append("")
            lines += _commented([key], doc, column)
            lines += _mapping_lines(hints[f.name], value, indent + 2, f.metadata.get("docs", {}))
        elif isinstance(value, (list, tuple)):
            lines += _commented(_flow_lines(f"{key} ", list(json_ready(value))), doc, column)
        else:
            lines += _commented([f"{key} {scalar_text(json_ready(value))}"], doc, column)
    return lines


def config_text() -> str:
    """The default config.yaml: every key with its default and its comment, sections in ``PipelineConfig``'s order."""
    lines = [*(f"# {line}" for line in CONFIG_HEADER), "", *_mapping_lines(PipelineConfig, PipelineConfig(), 0, {})]
    return "\n".join(lines) + "\n"


def _schema_lines(mapping: dict, indent: int, notes: dict[str, str] | None = None) -> list[str]:
    """A schema mapping as block YAML, each leaf schema one flow line when it fits in ``WIDTH``."""
    lines = []
    for key, value in mapping.items():
        prefix = " " * indent + f"{scalar_text(key)}:"
        flow = f"{prefix} {scalar_text(value)}"
        nested = isinstance(value, dict) and (key in ("properties", "$defs") or "properties" in value or len(flow) > WIDTH)
        if nested:
            if indent == 2 and "properties" in value and lines and lines[-1] != "":
                lines.append("")  # a blank line before each section, as in config.yaml
            lines += _commented([prefix], (notes or {}).get(key, ""), COMMENT_COLUMN)
            lines += _schema_lines(value, indent + 2)
        elif isinstance(value, list):
            lines += _flow_lines(f"{prefix} ", value)
        else:
            lines.append(flow)
    return lines


def schema_text() -> str:
    """The schema as YAML, the shared classes' ``$defs`` entries commented with where they are used."""
    schema = config_schema()
    usages = {_def_name(cls): f"{cls.__name__}: {', '.join(keys)}" for cls, keys in _usages(PipelineConfig).items()}
    defs = schema.pop("$defs")
    lines = [*(f"# {line}" for line in GENERATED_NOTE), *_schema_lines(schema, 0)]
    lines += ["", "# Shapes used in more than one section (one type each in the code as well).", "$defs:"]
    lines += _commented_defs(defs, usages)
    return "\n".join(lines) + "\n"


def _commented_defs(defs: dict, usages: dict[str, str]) -> list[str]:
    lines = []
    for name, schema in defs.items():
        lines += _commented([f"  {name}:"], usages[name], COMMENT_COLUMN)
        lines += _schema_lines(schema, 4)
    return lines


# --- the files


def generated_files() -> dict[Path, str]:
    """Each generated file and the text it must hold."""
    return {SCHEMA_PATH: schema_text(), DEFAULT_CONFIG_PATH: config_text()}


def stale_files() -> list[Path]:
    """The generated files whose text differs from what the settings classes give."""
    return [path for path, text in generated_files().items() if not path.is_file() or path.read_text() != text]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m dexlite_pipeline.config_files", description=__doc__.split("\n\n")[0])
    parser.add_argument("--write", action="store_true", help="rewrite the stale files (default: name them, exit 1)")
    args = parser.parse_args(argv)
    stale = stale_files()
    if args.write:
        for path, text in generated_files().items():
            if path in stale:
                path.write_text(text)
                print(f"wrote {path}")
        return 0
    for path in stale:
        print(f"{path} is stale: run `{REWRITE_COMMAND}`", file=sys.stderr)
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
