"""Grasp energies (force closure, contact distance, penetration, self-penetration, joint limits)."""

from dexlite_pipeline.energy.per_grasp import evaluate_grasp_energies
from dexlite_pipeline.energy.grasp_energy import (
    CONTACT_COUNT,
    TERM_NAMES,
    EnergyConfig,
    EnergyResult,
    EnergyWeights,
    GraspEnergy,
)
from dexlite_pipeline.energy.terms import EnergyContext, EnergyTerm

__all__ = [
    "CONTACT_COUNT",
    "TERM_NAMES",
    "EnergyConfig",
    "EnergyContext",
    "EnergyResult",
    "EnergyTerm",
    "EnergyWeights",
    "GraspEnergy",
    "evaluate_grasp_energies",
]
