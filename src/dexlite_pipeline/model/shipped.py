"""The pretrained model that ships with the source: where it is and which objects it was trained on.

The model of the large run (``config/profiles/large.yaml``) lives in the repository under
``models/shadow-hand-large/`` beside its model card (``MODEL_CARD.md``): a source checkout (and
an editable install) has it; a wheel does not, and then ``--model`` must name a file. The
default run samples it as its own method rows (``shipped_raw`` / ``shipped_post``) on the
held-out objects it never trained on; ``dexlite grasp`` uses it when no model is given.
"""

from __future__ import annotations

import os
from pathlib import Path

# models/ beside src/: this file is src/dexlite_pipeline/model/shipped.py
REPOSITORY_ROOT = Path(__file__).resolve().parents[3]
SHIPPED_MODEL_RELATIVE = Path("models") / "shadow-hand-large" / "cvae.pt"
SHIPPED_MODEL_PATH = REPOSITORY_ROOT / SHIPPED_MODEL_RELATIVE


def shipped_model_path() -> Path | None:
    """The shipped model file when this checkout has it, else None."""
    return SHIPPED_MODEL_PATH if SHIPPED_MODEL_PATH.is_file() else None


def model_or_shipped(model: str | os.PathLike | None) -> Path:
    """``model`` when given, else the shipped model; a clear error when neither exists."""
    if model:
        return Path(model)
    shipped = shipped_model_path()
    if shipped is None:
        raise FileNotFoundError(
            f"no --model given and no shipped model at {SHIPPED_MODEL_PATH} (a source checkout has it under {SHIPPED_MODEL_RELATIVE.parent})"
        )
    return shipped
