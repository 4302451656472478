"""The pretrained model that ships with the package: where it is and which objects it was trained on.

The model of the household profile (``config/profiles/household_model.yaml``: tabletop grasps of the
grasp dataset's household objects) is package data, in ``src/dexlite_pipeline/data/shadow-hand-household/``
beside its learned grasp evaluator (``evaluator.pt``) and its model card (``MODEL_CARD.md``, ``card.json``):
a checkout, an editable install, ``pip install .`` and a wheel all have them. The default run samples it as
its own method rows (``shipped_raw`` / ``shipped_post``) on the held-out objects it never trained on;
``dexlite grasp`` uses it, its samples ranked by the evaluator, when no model is given.
"""

from __future__ import annotations

import os
from pathlib import Path

# this file is dexlite_pipeline/model/shipped.py; the model is dexlite_pipeline/data/<SHIPPED_MODEL_DIR>/cvae.pt
PACKAGE_DATA = Path(__file__).resolve().parents[1] / "data"
SHIPPED_MODEL_DIR = "shadow-hand-household"
SHIPPED_MODEL_PATH = PACKAGE_DATA / SHIPPED_MODEL_DIR / "cvae.pt"
# The same file as a path in a source checkout (config.yaml's sample.shipped_model, read by the workflow).
SHIPPED_MODEL_RELATIVE = Path("src") / "dexlite_pipeline" / "data" / SHIPPED_MODEL_DIR / "cvae.pt"


# The learned grasp evaluator trained with the shipped model (``dexlite grasp`` ranks the shipped model's samples with it).
SHIPPED_EVALUATOR_PATH = SHIPPED_MODEL_PATH.with_name("evaluator.pt")


def shipped_evaluator_path() -> Path | None:
    """The shipped evaluator file, or None when none ships (or the package was installed without its data)."""
    return SHIPPED_EVALUATOR_PATH if SHIPPED_EVALUATOR_PATH.is_file() else None


def shipped_model_path() -> Path | None:
    """The shipped model file, or None when the package was installed without its data."""
    return SHIPPED_MODEL_PATH if SHIPPED_MODEL_PATH.is_file() else None


def model_or_shipped(model: str | os.PathLike | None) -> Path:
    """``model`` when given, else the shipped model; a clear error when neither exists."""
    if model:
        return Path(model)
    shipped = shipped_model_path()
    if shipped is None:
        raise FileNotFoundError(
            f"no --model given and no shipped model at {SHIPPED_MODEL_PATH} (the package was installed without its data)"
        )
    return shipped
