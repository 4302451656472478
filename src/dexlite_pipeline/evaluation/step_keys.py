"""Which ``evaluate`` settings each evaluation step reads, and which grasp stores each method comes from.

Changing a setting reruns only the steps that read it.

The workflow passes each step only its keys of the ``evaluate`` section (Snakemake tracks a
rule's params), and the steps themselves drop every other key before reading the section,
so a step behaves the same whether the rule or a user calling the CLI with the whole
section runs it. The report step reads the whole config (it is the last stage and records it).
This module imports nothing heavy (the config tree): the workflow imports it while it parses the rules.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from dexlite_pipeline.config import rule_keys
from dexlite_pipeline.evaluation.config import EvaluateConfig

# Each key of EvaluateConfig names the rules that read it (``setting(rules=...)``).
# evaluate --step simulate (rule evaluate_simulate): which grasps are chosen and how they are measured
SIMULATE_KEYS = rule_keys(EvaluateConfig, "evaluate_simulate")
# evaluate --step aggregate (rule evaluate): which rows metrics.csv has, how diversity is measured and the equal energy
# filter (the aggregate step also reads the config section diversity: its rule tracks that section too)
AGGREGATE_KEYS = rule_keys(EvaluateConfig, "evaluate")
# dexlite report: pictures per method (its rule passes the whole config, which the report shows)
REPORT_KEYS = rule_keys(EvaluateConfig, "report")


def with_evaluate_keys(config: Mapping, keys: Sequence[str]) -> dict:
    """``config`` with its ``evaluate`` section cut down to ``keys`` (the other sections as they are)."""
    section = config.get("evaluate") or {}
    return {**config, "evaluate": {key: section[key] for key in keys if key in section}}


# Grasp stores the evaluation reads: source -> its CLI option of ``dexlite evaluate``.
SOURCE_OPTIONS = {"optimized": "optimized", "sample": "sample", "post": "post", "random_post": "random-post", "dexgraspnet": "dexgraspnet"}
# Method (row of metrics.csv) -> the store its grasps are read from.
METHOD_SOURCES = {
    "optimization": "optimized", "random_post": "random_post", "dexgraspnet": "dexgraspnet",
    "cvae_raw": "sample", "cvae_recon": "sample", "cvae_prior_train": "sample",
    "cvae_post": "post", "cvae_recon_post": "post", "cvae_prior_train_post": "post",
    "shipped_raw": "sample", "shipped_post": "post", "cvae_ranked": "sample", "cvae_ranked_post": "post",
}  # fmt: skip


def sources_of(methods: Sequence[str]) -> list[str]:
    """The stores (keys of ``SOURCE_OPTIONS``) that ``methods`` read, in ``SOURCE_OPTIONS`` order.

    Post-optimized CVAE methods also read the sampled store: their rows are chosen among the
    sampled rows, and the ladder's reference poses are kept there.
    """
    needed = {METHOD_SOURCES[m] for m in methods if m in METHOD_SOURCES}
    if "post" in needed:
        needed.add("sample")
    return [source for source in SOURCE_OPTIONS if source in needed]
