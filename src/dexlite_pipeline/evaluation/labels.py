"""Readable names and cell texts for the evaluation's tables: method, split and rung labels, percentages,
intervals and seconds, as the report shows them."""

from __future__ import annotations

import math

# Readable names for the method ids of metrics.csv; an id not listed here is shown by
# ``method_label``'s fallback (words of the id, "+ post-optimization" for a ``_post`` suffix).
METHOD_LABELS = {
    "optimization": "Optimization from scratch",
    "cvae_raw": "CVAE samples, raw",
    "cvae_post": "CVAE samples + post-optimization",
    "random_post": "Random start + post-optimization",
    "dexgraspnet": "DexGraspNet grasps (imported)",
    "cvae_recon": "CVAE reconstructions, raw",
    "cvae_recon_post": "CVAE reconstructions + post-optimization",
    "cvae_prior_train": "CVAE samples on training objects, raw",
    "cvae_prior_train_post": "CVAE samples on training objects + post-optimization",
    "shipped_raw": "Shipped model's samples, raw",
    "shipped_post": "Shipped model's samples + post-optimization",
    "cvae_ranked": "CVAE samples ranked by the evaluator, raw",
    "cvae_ranked_post": "CVAE samples ranked by the evaluator + post-optimization",
}
SPLIT_LABELS = {"heldout": "held-out objects", "train": "training objects"}
# The learning ladder's rungs (metrics.csv column ``rung``), in the order they are read.
RUNG_LABELS = {
    "fit": "1 · fit: training grasps encoded and decoded",
    "in_distribution": "2 · in distribution: samples on training objects",
    "heldout": "3 · held out: samples on unseen objects",
}


def method_label(method: str) -> str:
    """A reader's name for a method id (``cvae_post`` -> "CVAE samples + post-optimization")."""
    method = str(method)
    if method in METHOD_LABELS:
        return METHOD_LABELS[method]
    base, post = (method[: -len("_post")], True) if method.endswith("_post") else (method, False)
    words = " ".join("CVAE" if w == "cvae" else w for w in base.split("_") if w)
    words = words[:1].upper() + words[1:]
    return f"{words} + post-optimization" if post else words


def split_label(split: str) -> str:
    return SPLIT_LABELS.get(str(split), str(split))


def rung_label(rung: str) -> str:
    return RUNG_LABELS.get(str(rung), str(rung))


def percent_text(fraction) -> str:
    """A fraction as a percentage with one decimal ("17.5%"); "not run" for NaN or None."""
    try:
        value = float(fraction)
    except (TypeError, ValueError):
        return "not run"
    return f"{100 * value:.1f}%" if math.isfinite(value) else "not run"


def interval_text(low, high) -> str:
    """A 95% interval of fractions as whole percentages ("43–66"); empty when either end is missing."""
    try:
        low, high = float(low), float(high)
    except (TypeError, ValueError):
        return ""
    if not (math.isfinite(low) and math.isfinite(high)):
        return ""
    return f"{100 * low:.0f}–{100 * high:.0f}"


def seconds_text(seconds) -> str:
    """Seconds per grasp for a table cell: "0.35 s", "21 ms", "—" when unknown."""
    try:
        value = float(seconds)
    except (TypeError, ValueError):
        return "—"
    if not math.isfinite(value):
        return "—"
    if value < 0.1:
        return f"{1000 * value:.2g} ms" if value * 1000 < 10 else f"{1000 * value:.0f} ms"
    return f"{value:.2g} s" if value < 10 else f"{value:.0f} s"
