"""Command-line options the training stages share (``train_cvae``, ``loop_train``): where an unfinished training keeps
its state (``model.training_state``) and how often it writes it."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_training_state_arguments(parser: argparse.ArgumentParser) -> None:
    """``--training-state``, ``--state-every-s`` and ``--no-training-state``."""
    parser.add_argument("--training-state", help="where the unfinished training's state is kept (default: beside --model, "
                        "<model>.state): saved at epoch ends, looked for at the start, so that a rerun after an interruption "
                        "goes on from it to the same model; removed once the model is written")
    parser.add_argument("--state-every-s", type=float, default=300.0, help="seconds between saves of the training state "
                        "(at epoch ends; 0 = every epoch; default 300)")
    parser.add_argument("--no-training-state", action="store_true", help="neither save nor look for a training state")


def training_state_path(args: argparse.Namespace) -> Path | None:
    """The state file the options name (None with ``--no-training-state``); ValueError for a negative interval."""
    if args.state_every_s < 0:
        raise ValueError(f"--state-every-s must be >= 0, got {args.state_every_s}")
    if args.no_training_state:
        return None
    return Path(args.training_state) if args.training_state else default_state_path(args.model)


def default_state_path(model_path: str | Path) -> Path:
    """Where ``train_cvae`` and ``loop_train`` keep an unfinished training's state: beside the model, ``<model>.state``."""
    return Path(model_path).with_name(Path(model_path).name + ".state")
