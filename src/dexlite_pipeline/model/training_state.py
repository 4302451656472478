"""A training's state between epochs, so that an interrupted training goes on where it stopped.

A whole-dataset training takes about an hour on two cores; a SLURM job's time limit, a session's end or a killed
process would otherwise lose all of it. ``train_cvae`` saves, at the end of an epoch (at most once per
``every_s`` seconds), everything the next epoch depends on: the weights, Adam's moments, the learning-rate
schedule's position, the batch order's and the noise's random streams, the step and the history. Started again
with the same data, config and seed, it loads the state and runs the remaining epochs; the model it ends with is
the one an uninterrupted run makes, bit for bit on the same machine and thread count.

A state records a fingerprint of what determines the training (config section ``train``, seed, the training and
validation grasps, their poses and clouds, and a warm start's weights). A state of another fingerprint is not
used: the training starts afresh and overwrites it. The file is written atomically (a kill while writing leaves the
previous state) and loads with ``torch.load(weights_only=True)``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from dexlite_pipeline.atomic import atomic_path

log = logging.getLogger(__name__)

STATE_FORMAT = 1


def training_fingerprint(config, seed: int, data, train_index: np.ndarray, val_index: np.ndarray, initial_model=None,
                         context: dict | None = None) -> str:
    """A hex digest of what determines a training's course: ``config`` (a ``TrainConfig``), ``seed``, the training and
    validation rows, the grasps' pose features, types, objects and scales, the objects' surface samples and tables and,
    for a warm start, the initial weights; ``context``: what else the caller's loss depends on (JSON-able)."""
    digest = hashlib.sha256()
    digest.update(json.dumps(context or {}, sort_keys=True, default=str).encode())
    digest.update(json.dumps(dataclasses.asdict(config), sort_keys=True, default=str).encode())
    digest.update(str(int(seed)).encode())
    for index in (train_index, val_index):
        digest.update(np.ascontiguousarray(np.asarray(index, np.int64)).tobytes())
        digest.update(b"|")
    digest.update(data.pose_features.detach().cpu().numpy().tobytes())
    for tensor in (data.grasp_type, data.clouds.surface, data.clouds.normals, data.clouds.upright):
        digest.update(tensor.detach().cpu().numpy().tobytes())
    for array in (data.object_index, data.scale):
        digest.update(np.ascontiguousarray(np.asarray(array, np.float64)).tobytes())
    digest.update(json.dumps([list(data.clouds.object_ids), list(data.type_vocabulary)]).encode())
    if initial_model is not None:
        for name, tensor in initial_model.state_dict().items():
            digest.update(name.encode())
            digest.update(tensor.detach().cpu().numpy().tobytes())
    return digest.hexdigest()


@dataclass
class TrainingStateFile:
    """Where a training keeps its state (``path``) and how often it writes it (``every_s``: seconds between writes,
    at epoch ends; 0 = after every epoch). ``context``: what the loss depends on beyond the config section ``train``
    and the data (the hand, the self-penetration margin, the table), part of the fingerprint."""

    path: Path
    every_s: float = 300.0
    context: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        self.path = Path(self.path)
        if self.every_s < 0:
            raise ValueError(f"training state: every_s must be >= 0, got {self.every_s}")
        self._last_write = time.monotonic()

    def due(self) -> bool:
        """Whether an epoch that just ended should write the state."""
        return self.every_s == 0 or time.monotonic() - self._last_write >= self.every_s

    def save(self, fingerprint: str, *, epoch: int, step: int, seconds: float, history: list[dict], model, optimizer,
             scheduler, batch_rng: np.random.Generator, generator: torch.Generator) -> None:
        """Write the state after epoch ``epoch`` (``step`` optimizer steps, ``seconds`` of training so far)."""
        state = {
            "format": STATE_FORMAT,
            "fingerprint": fingerprint,
            "epoch": int(epoch),
            "step": int(step),
            "seconds": float(seconds),
            "history": json.dumps(history),
            "model": model.state_dict(),
            "optimizer": optimizer.state_dict(),
            "scheduler": scheduler.state_dict(),
            "batch_rng": json.dumps(batch_rng.bit_generator.state),
            "generator": generator.get_state(),
            "torch_rng": torch.get_rng_state(),
        }
        with atomic_path(self.path) as tmp:
            torch.save(state, tmp)
        self._last_write = time.monotonic()
        log.info("training state after epoch %d (step %d) saved to %s", epoch, step, self.path)

    def load(self, fingerprint: str) -> dict | None:
        """The saved state when it exists and has ``fingerprint``; None otherwise (logged when a state is set aside)."""
        if not self.path.exists():
            return None
        try:
            state = torch.load(self.path, map_location="cpu", weights_only=True)
        except Exception as exc:  # a truncated or foreign file: start afresh, say why
            log.warning("%s: not a readable training state (%s); training from the start", self.path, exc)
            return None
        if state.get("format") != STATE_FORMAT or state.get("fingerprint") != fingerprint:
            log.warning("%s: a training state of other data, config or seed; training from the start", self.path)
            return None
        state["history"] = json.loads(state["history"])
        state["batch_rng"] = json.loads(state["batch_rng"])
        return state


def restore(state: dict, *, model, optimizer, scheduler, batch_rng: np.random.Generator, generator: torch.Generator) -> None:
    """Put a loaded state back into the training's objects (in place)."""
    device = next(model.parameters()).device
    model.load_state_dict(state["model"])
    optimizer.load_state_dict(state["optimizer"])
    for values in optimizer.state.values():  # Adam's moments follow the model's device
        for key, value in values.items():
            if torch.is_tensor(value) and key != "step":
                values[key] = value.to(device)
    scheduler.load_state_dict(state["scheduler"])
    batch_rng.bit_generator.state = state["batch_rng"]
    generator.set_state(state["generator"])
    torch.set_rng_state(state["torch_rng"])
