"""Colour checks on rendered pictures, shared by the render and 3-D view tests."""

from __future__ import annotations

import numpy as np


def colour_fraction(image: np.ndarray, rgb, tolerance: float = 0.12) -> float:
    """Fraction of pixels whose colour is a shade of ``rgb`` (same hue, any brightness)."""
    pixels = image[..., :3].reshape(-1, 3).astype(np.float64)
    norm = np.linalg.norm(pixels, axis=1, keepdims=True)
    target = np.asarray(rgb) / np.linalg.norm(rgb)
    direction = np.divide(pixels, norm, out=np.zeros_like(pixels), where=norm > 0.05)
    return float((np.linalg.norm(direction - target, axis=1) < tolerance).mean())
