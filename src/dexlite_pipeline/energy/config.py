"""The energy's config types: section ``energy``, the term weights and the energy thresholds.

A leaf of the config tree (``settings``): it imports no energy code, so a stage's code hash
(``codehash``) covers these shapes without the computation. ``EnergyThresholds`` is the one type
for every place that thresholds energies: optimization from scratch marks ``passes_energy_thresholds`` with
it (``optimize_grasps.thresholds``) and curation filters with it (``curate.thresholds``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# Mean spacing (m) of the object points of the judged penetration depth: every check of whether a grasp starts
# inside its object (the energy filter, the optimizers' reported depth and contact resolution, the lift test's
# start check) samples this densely, whatever spacing the energy's own E_pen uses (``object_point_spacing_m``).
JUDGED_POINT_SPACING_M = 0.002

# DexGraspNet's success criteria: a grasp passes when each term is below its value (E_dis, E_pen in metres).
DEXGRASPNET_THRESHOLDS: dict[str, float] = {"E_fc": 0.3, "E_dis": 0.005, "E_pen": 0.001}


@dataclass(frozen=True)
class EnergyThresholds:
    """A grasp passes when each term is below its threshold: E_fc (unitless), E_dis and E_pen (metres)."""

    max_e_fc: float = DEXGRASPNET_THRESHOLDS["E_fc"]  # force-closure residual ‖Σn‖² + ‖Σx×n‖²
    max_e_dis_m: float = DEXGRASPNET_THRESHOLDS["E_dis"]  # contact distance Σ|d| over the four contacts, m
    max_e_pen_m: float = DEXGRASPNET_THRESHOLDS["E_pen"]  # penetration depth sum, m
    max_penetration_m: float = 0.002  # penetration depth (the one measure, ``penetration_mm``), m: the lift test's start cap

    def __post_init__(self) -> None:
        for name in ("max_e_fc", "max_e_dis_m", "max_e_pen_m", "max_penetration_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"thresholds.{name} must be positive, got {getattr(self, name)}")

    def limits(self) -> dict[str, float]:
        """Array name -> threshold: E_fc, E_dis, E_pen and the penetration depth ``penetration_mm`` (in mm, as stored)."""
        return {"E_fc": self.max_e_fc, "E_dis": self.max_e_dis_m, "E_pen": self.max_e_pen_m, "penetration_mm": self.max_penetration_m * 1000.0}

    def passes(self, terms: dict) -> np.ndarray:
        """(B,) bool: every thresholded array of ``terms`` (arrays by name, ``limits``) is below its limit.

        The depth passes at exactly the cap (≤, as the lift test's start check); the energies below it.
        """
        passing = None
        for name, limit in self.limits().items():
            values = np.asarray(terms[name])
            below = values <= limit if name == "penetration_mm" else values < limit
            passing = below if passing is None else passing & below
        return passing


@dataclass(frozen=True)
class EnergyWeights:
    """Weights of the terms in the total energy (defaults: DexGraspNet's and E_post's)."""

    fc: float = 1.0
    dis: float = 100.0
    pen: float = 100.0
    spen: float = 10.0
    joints: float = 1.0
    table: float = 100.0  # E_table, tabletop mode only (a term of its own, never in ``combined_energy``'s five)


@dataclass(frozen=True)
class EnergyConfig:
    """Config section ``energy``: term weights and how the terms are sampled."""

    weights: EnergyWeights = field(default_factory=EnergyWeights)
    object_point_spacing_m: float = 0.004  # mean spacing of E_pen's object surface points at the grasp's scale, m
    self_penetration_margin_m: float = 0.02  # E_spen distance below which keypoint pairs are penalized
