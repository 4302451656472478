# Shared helpers for the rules: config validation, per-stage params, shard lists.
import json

from snakemake.utils import validate

from dexlite_pipeline.config import SCHEMA_PATH, section_json

validate(config, str(SCHEMA_PATH))

RESULTS = "results"
LOGS = "logs"
SHARDS = [f"{i:03d}" for i in range(int(config["shards"]))]


def stage_params(*sections):
    """Canonical JSON of the config sections a stage uses: changes rerun exactly that stage."""
    return section_json(config, *sections)


def final_outputs():
    """The final products of the stages that exist."""
    return [f"{RESULTS}/objects/catalog.parquet"]
