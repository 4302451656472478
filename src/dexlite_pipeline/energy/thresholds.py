"""The energy thresholds a grasp must meet (DexGraspNet's success criteria).

One type for every place that thresholds energies: seed synthesis marks
``passes_energy_thresholds`` with it (``seed_grasps.thresholds``) and curation filters with it
(``curate.thresholds``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dexlite_pipeline.energy.grasp_energy import DEXGRASPNET_THRESHOLDS


@dataclass(frozen=True)
class EnergyThresholds:
    """A grasp passes when each term is below its threshold: E_fc (unitless), E_dis and E_pen (metres)."""

    max_e_fc: float = DEXGRASPNET_THRESHOLDS["E_fc"]  # force-closure residual ‖Σn‖² + ‖Σx×n‖²
    max_e_dis_m: float = DEXGRASPNET_THRESHOLDS["E_dis"]  # contact distance Σ|d| over the four contacts, m
    max_e_pen_m: float = DEXGRASPNET_THRESHOLDS["E_pen"]  # penetration depth sum, m

    def __post_init__(self) -> None:
        for name in ("max_e_fc", "max_e_dis_m", "max_e_pen_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"thresholds.{name} must be positive, got {getattr(self, name)}")

    def limits(self) -> dict[str, float]:
        """Term name -> threshold (E_fc, E_dis, E_pen)."""
        return {"E_fc": self.max_e_fc, "E_dis": self.max_e_dis_m, "E_pen": self.max_e_pen_m}

    def passes(self, terms: dict) -> np.ndarray:
        """(B,) bool: every thresholded term of ``terms`` (arrays by term name) is below its limit."""
        passing = None
        for name, limit in self.limits().items():
            below = np.asarray(terms[name]) < limit
            passing = below if passing is None else passing & below
        return passing
