"""The pretrained models that ship with the package, one folder per hand: where they are.

The Shadow Hand's model of the household profile (``config/profiles/household_model.yaml``: tabletop grasps of the
grasp dataset's household objects) is package data, in ``src/dexlite_pipeline/data/shadow-hand-household/``
beside its learned grasp evaluator (``evaluator.pt``) and its model card (``MODEL_CARD.md``, ``card.json``):
a checkout, an editable install, ``pip install .`` and a wheel all have them. The default run samples it as
its own method rows (``shipped_raw`` / ``shipped_post``) on the held-out objects it never trained on;
``dexlite grasp`` uses it, its samples ranked by the evaluator, when no model is given. Another shipped hand's
model (``SHIPPED_MODEL_DIRS``: the household model of that hand, trained on its dataset folder) is laid out the
same way and serves ``dexlite grasp --hand <name>`` and ``model_batch.model: shipped`` for that hand; a hand
without one (an MJCF file, or a shipped hand whose folder is absent) has no shipped model.
"""

from __future__ import annotations

import os
from pathlib import Path

# this file is dexlite_pipeline/model/shipped.py; the model is dexlite_pipeline/data/<SHIPPED_MODEL_DIR>/cvae.pt
PACKAGE_DATA = Path(__file__).resolve().parents[1] / "data"
SHIPPED_MODEL_DIRS = {"shadow": "shadow-hand-household", "allegro": "allegro-hand-household", "leap": "leap-hand-household"}
SHIPPED_MODEL_DIR = SHIPPED_MODEL_DIRS["shadow"]
SHIPPED_MODEL_PATH = PACKAGE_DATA / SHIPPED_MODEL_DIR / "cvae.pt"
# The same file as a path in a source checkout (config.yaml's sample.shipped_model, read by the workflow).
SHIPPED_MODEL_RELATIVE = Path("src") / "dexlite_pipeline" / "data" / SHIPPED_MODEL_DIR / "cvae.pt"


def shipped_file(hand: str, name: str) -> Path | None:
    """``name`` (cvae.pt, evaluator.pt, ...) in the folder of ``hand``'s shipped model (config key ``hand``: a shipped
    hand's name or an MJCF path), or None when that hand has no shipped model or the file is absent (the package
    installed without its data)."""
    folder = SHIPPED_MODEL_DIRS.get(str(hand))
    path = PACKAGE_DATA / folder / name if folder else None
    return path if path is not None and path.is_file() else None


def shipped_evaluator_path(hand: str = "shadow") -> Path | None:
    """The evaluator shipped with ``hand``'s model, or None when none ships (or the package was installed without its data)."""
    return shipped_file(hand, "evaluator.pt")


SHIPPED = "shipped"  # a config value or argument that names the model (or evaluator) shipped for the hand
TRAINED_BY_THE_RUN = "train"


def ranking_evaluator_file(source: str, hand: str = "shadow", base: str | os.PathLike = ".") -> Path | None:
    """The evaluator file config key ``evaluator.source`` names: None for ``train`` (the run trains its own), the
    package's evaluator of ``hand`` for ``shipped``, else the path (relative to ``base``, the run folder). Raises
    FileNotFoundError in one line naming the key when the file does not exist."""
    if source == TRAINED_BY_THE_RUN:
        return None
    if source == SHIPPED:
        path = shipped_evaluator_path(hand)
        if path is None:
            raise FileNotFoundError(f"evaluator.source: shipped: {missing_shipped_model_reason(hand)} (no shipped evaluator)")
        return path
    path = Path(base) / Path(source).expanduser()
    if not path.is_file():
        raise FileNotFoundError(f"evaluator.source: {source}: no such evaluator file")
    return path


def shipped_model_path(hand: str = "shadow") -> Path | None:
    """``hand``'s shipped model file, or None when that hand has none (or the package was installed without its data)."""
    return shipped_file(hand, "cvae.pt")


def missing_shipped_model_reason(hand: str = "shadow") -> str:
    """Why ``hand`` has no shipped model, in words for a one-line error."""
    folder = SHIPPED_MODEL_DIRS.get(str(hand))
    if folder is None:
        shipped = [name for name in SHIPPED_MODEL_DIRS if shipped_file(name, "cvae.pt") is not None]
        return f"no model ships for hand {hand} (shipped models: {', '.join(shipped) or 'none'})"
    return f"no shipped model at {PACKAGE_DATA / folder / 'cvae.pt'} (not shipped for hand {hand}, or the package was installed without its data)"


def model_or_shipped(model: str | os.PathLike | None, hand: str = "shadow") -> Path:
    """``model`` when given, else ``hand``'s shipped model; a clear error when neither exists."""
    if model:
        return Path(model)
    shipped = shipped_model_path(hand)
    if shipped is None:
        raise FileNotFoundError(f"no --model given and {missing_shipped_model_reason(hand)}")
    return shipped
