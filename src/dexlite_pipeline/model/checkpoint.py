"""The trained model on disk: a state dict plus the config it was trained with.

Everything in the file is tensors, numbers, strings, lists and dicts, so it loads with
``torch.load(path, weights_only=True)`` (no pickled code is executed).
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import torch

from dexlite_pipeline.io.atomic import atomic_path
from dexlite_pipeline.model.network import GraspCVAE, ModelConfig

CHECKPOINT_FORMAT = "dexlite-cvae-1"


class CheckpointError(ValueError):
    """A model file that is missing or not a DexLite CVAE checkpoint."""


def save_checkpoint(path: str | os.PathLike, model: GraspCVAE, train_config, extra: dict) -> Path:
    """Write the model's weights, its ModelConfig, the training config and ``extra`` (JSON-like) atomically."""
    payload = {
        "format": CHECKPOINT_FORMAT,
        "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        "model_config": model.config.to_dict(),
        "train_config": json.loads(json.dumps(dataclasses.asdict(train_config))),
        **json.loads(json.dumps(extra)),
    }
    with atomic_path(path) as tmp:
        torch.save(payload, tmp)
    return Path(path)


def load_checkpoint(path: str | os.PathLike, device: torch.device | str = "cpu") -> tuple[GraspCVAE, dict]:
    """The model in eval mode on ``device`` and the checkpoint's other entries."""
    p = Path(path)
    if not p.is_file():
        raise CheckpointError(f"{p}: model checkpoint not found")
    try:
        payload = torch.load(p, map_location=device, weights_only=True)
    except Exception as exc:  # torch raises several types for a foreign or corrupt file
        raise CheckpointError(f"{p}: cannot load as a weights-only checkpoint ({exc})") from exc
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(f"{p}: not a {CHECKPOINT_FORMAT} checkpoint")
    model = GraspCVAE(ModelConfig.from_dict(payload["model_config"])).to(device)
    model.load_state_dict(payload["state_dict"])
    model.eval()
    return model, {k: v for k, v in payload.items() if k != "state_dict"}
