"""Stage ``train_evaluator``: the learned grasp evaluator, trained on the run's simulated grasps of its training
objects (lift-validated shards and on-generator examples; ``evaluator.training``).

Writes ``--out`` (weights, config and the training facts; ``model.evaluator.load_evaluator``) and ``--facts``
(the same facts as JSON: objects, examples per source, what was left out, per-epoch history, validation AUC).
"""

from __future__ import annotations

import argparse
import json
import logging

log = logging.getLogger("dexlite.train_evaluator")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config-json", required=True, help="config sections seed, device, hand and evaluator (JSON)")
    parser.add_argument("--lift", action="append", default=[], help="a lift-validated grasp shard (repeatable)")
    parser.add_argument("--examples", action="append", default=[], help="an evaluator_examples shard (repeatable)")
    parser.add_argument("--objects", action="append", required=True, help="prepared objects dir with catalog.parquet (repeatable)")
    parser.add_argument("--out", required=True, help="output evaluator file (evaluator.pt)")
    parser.add_argument("--facts", required=True, help="output training facts (.json)")


# The keys of section ``evaluator`` the training reads (workflow/rules/evaluator.smk passes only these).
TRAINING_KEYS = ("epochs", "hand_points_per_shape", "validation_fraction")


def run(args: argparse.Namespace) -> int:
    from dexlite_pipeline.atomic import atomic_path
    from dexlite_pipeline.config import json_ready
    from dexlite_pipeline.evaluator.training import train_from_run
    from dexlite_pipeline.model.evaluator import save_evaluator
    from dexlite_pipeline.settings import stage_config

    config = stage_config(args.config_json)
    seed = config.train.training_seed(config.seed)
    model, facts = train_from_run(args.lift, args.examples, args.objects, config.evaluator, seed, config.device, config.hand)
    section = json_ready(config.evaluator)
    used = {key: section[key] for key in TRAINING_KEYS}  # what this stage reads (the section's other keys are other stages')
    facts = {**facts, "config": {"seed": seed, "evaluator": used}}
    save_evaluator(args.out, model, model.config, facts)
    with atomic_path(args.facts) as tmp:
        with open(tmp, "w") as handle:
            json.dump(json_ready(facts, nan_as_none=True), handle, indent=1)
    log.info("wrote %s: %d examples on %d training objects, validation AUC (held) %s", args.out, facts["examples"],
             len(facts["train_object_ids"]), facts["validation_auc_held"])
    return 0
