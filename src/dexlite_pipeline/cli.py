"""The dexlite command: user commands for your own meshes and grasp stores, and the pipeline's stages.

Each pipeline stage's command lives in ``dexlite_pipeline.stages.<module>``, each user tool's in
``dexlite_pipeline.commands.<module>``; both expose
``add_arguments(parser)`` and ``run(args) -> int``; modules are imported only when
their command runs, so ``dexlite --help`` is fast and one stage's heavy dependencies
never slow another.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import re
import sys

from dexlite_pipeline import __version__

# Commands for users, in the order of the help: command -> (module, help).
USER_COMMANDS: dict[str, tuple[str, str]] = {
    "grasp": ("commands.grasp", "grasps that hold for your own meshes: prepare, synthesize, test, export, summarize"),
    "lift-test": ("commands.lift_test", "MuJoCo lift test (and optional six-direction test) of every grasp in a store"),
    "energy": ("commands.energy", "per-grasp energy terms and penetration depth of a grasp store"),
    "render": ("commands.render", "render one grasp (hand and object) to a PNG"),
    "import-dexgraspnet": ("stages.import_dexgraspnet", "import a DexGraspNet download as a grasp store plus object assets"),
    "export-dexgraspnet": ("commands.export_dexgraspnet", "write a grasp store in the DexGraspNet layout"),
    "dataset-add": ("commands.dataset_add", "add a finished run's data stages to a grasp dataset as one batch (campaigns)"),
    "hand-check": ("commands.hand_check", "what a hand's MJCF gives the pipeline (joints, collision shapes, contacts, palm) and its FK against MuJoCo"),
}
# The pipeline's stages, in the order they run (Snakemake calls them, one rule each).
PIPELINE_STAGES: dict[str, tuple[str, str]] = {
    "prepare-objects": ("stages.prepare_objects", "normalize meshes, decompose, build SDF grids and point clouds"),
    "stability-filter": ("stages.stability_filter", "PyBullet table-stability test of prepared objects"),
    "optimize-grasps": ("stages.optimize_grasps", "grasps by energy optimization from scratch (one shard)"),
    "dataset-grasps": ("stages.dataset_grasps", "a grasp dataset's grasps of the training objects, as training data (dataset.root)"),
    "curate": ("stages.curate", "filter optimized/imported grasps by stability, energy thresholds and duplicates"),
    "lift-validate": ("stages.lift_validate", "lift-test one shard of curated grasps"),
    "model-batch": ("stages.model_batch", "a dataset batch made by the model, optimization from scratch topping up (one shard)"),
    "train-cvae": ("stages.train_cvae", "train the PointNet + CVAE grasp model"),
    "evaluator-examples": ("stages.evaluator_examples", "learned evaluator: the model's syntheses on training objects, refined and simulated"),
    "train-evaluator": ("stages.train_evaluator", "learned evaluator: train it on the run's simulated grasps of training objects"),
    "sample-grasps": ("stages.sample_grasps", "sample grasps from the trained CVAE"),
    "post-optimize": ("stages.post_optimize", "refine sampled grasps by annealed energy optimization"),
    "loop-initial-set": ("stages.loop_initial_set", "data loop: round 0's grasp set (the first model's training grasps)"),
    "loop-sample": ("stages.loop_sample", "data loop: sample a round's grasps with a model (one shard)"),
    "loop-post-optimize": ("stages.loop_post_optimize", "data loop: refine a round's sampled grasps (one shard)"),
    "loop-validate": ("stages.loop_validate", "data loop: energy filter, lift and six-direction tests of a round's grasps"),
    "loop-merge": ("stages.loop_merge", "data loop: add a round's new distinct grasps to the set"),
    "loop-train": ("stages.loop_train", "data loop: train a round's model, warm-started"),
    "loop-summary": ("stages.loop_summary", "data loop: a round's table and its row of results/loop.csv"),
    "loop-table": ("stages.loop_table", "data loop: results/loop.csv over the rounds"),
    "evaluate": ("stages.evaluate", "simulate and measure every method on held-out objects"),
    "report": ("stages.report", "build results/eval/report.html from the evaluation outputs"),
}
COMMANDS: dict[str, tuple[str, str]] = {**USER_COMMANDS, **PIPELINE_STAGES}
DESCRIPTION = "DexLite: grasps that hold for the Shadow Hand, on your own meshes, and the pipeline that learns to make them."
HELP_WIDTH = 22  # column of the commands' descriptions in ``dexlite --help``


def commands_help() -> str:
    """The grouped command list of ``dexlite --help``, plain text."""
    lines = ["commands for your meshes and grasp stores:"]
    lines += [f"  {name:<{HELP_WIDTH - 2}}{text}" for name, (_, text) in USER_COMMANDS.items()]
    lines += ["", "pipeline stages (Snakemake runs them, one rule each: snakemake --cores 2 all):"]
    lines += [f"  {name:<{HELP_WIDTH - 2}}{text}" for name, (_, text) in PIPELINE_STAGES.items()]
    lines += ["", "dexlite COMMAND --help shows a command's options. Start with: dexlite grasp MESH --out DIR"]
    return "\n".join(lines)


class CliError(Exception):
    """An error to print as one line and exit with status 2."""


class OneLineParser(argparse.ArgumentParser):
    """A command's argument parser whose errors are one line (``dexlite COMMAND: error: ...``), exit status 2."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dexlite", description=DESCRIPTION, epilog=commands_help(), formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"dexlite {__version__}")
    parser.add_argument("--log-level", default="INFO", choices=["DEBUG", "INFO", "WARNING", "ERROR"])
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, help="one of the commands below")
    for name in COMMANDS:  # listed, grouped, by the epilog
        sub.add_parser(name, add_help=False)
    return parser


# OpenMP threads that spin while they wait for each other make torch at 2 threads several
# times slower than at 1 whenever the cores are shared; waiting passively costs nothing when idle.
# It must be set before torch starts its OpenMP runtime, so before any stage is imported.
OPENMP_ENVIRONMENT = {"OMP_WAIT_POLICY": "PASSIVE"}


def main(argv: list[str] | None = None) -> int:
    for name, value in OPENMP_ENVIRONMENT.items():
        os.environ.setdefault(name, value)
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    top, rest = parser.parse_known_args(argv)
    module_name, help_text = COMMANDS[top.command]
    module = importlib.import_module(f"dexlite_pipeline.{module_name}")
    stage_parser = OneLineParser(prog=f"dexlite {top.command}", description=help_text)
    stage_parser.add_argument("--threads", type=int, default=None, help="torch/worker threads (Snakemake passes the rule's threads)")
    module.add_arguments(stage_parser)
    args = stage_parser.parse_args(rest)
    logging.basicConfig(level=top.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s", stream=sys.stderr)
    from dexlite_pipeline.device import set_threads

    set_threads(args.threads)
    try:
        return int(module.run(args) or 0)
    except (CliError, ValueError, OSError) as exc:  # bad input or an unreadable/unwritable file: one line, no traceback
        print(f"dexlite {top.command}: error: {error_text(exc)}", file=sys.stderr)
        return 2


# Outputs are written to a hidden sibling ``.NAME.tmp-XXXXXXXX`` and renamed into place
# (``dexlite_pipeline.atomic``); an error on the sibling is reported with the path the user gave.
TEMPORARY_SIBLING = re.compile(r"\.(?P<name>.+)\.tmp-[0-9a-f]{8}")


def user_path(path: str) -> str:
    """``path`` with a temporary output sibling replaced by the final output path."""
    head, tail = os.path.split(str(path))
    match = TEMPORARY_SIBLING.fullmatch(tail)
    return os.path.join(head, match["name"]) if match else str(path)


def error_text(exc: BaseException) -> str:
    """The one-line message of ``exc``, naming the user's paths rather than temporary siblings."""
    if isinstance(exc, OSError) and exc.filename is not None:
        text = f"{user_path(exc.filename)}: {exc.strerror or type(exc).__name__}"
        if exc.filename2 is not None:
            text += f" (and {user_path(exc.filename2)})"
        return text
    return " ".join(user_path(w) if ".tmp-" in w else w for w in str(exc).split(" ")) or type(exc).__name__


if __name__ == "__main__":
    sys.exit(main())
