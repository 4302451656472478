"""Grasp energies (force closure, contact distance, penetration, self-penetration, joint limits).

Importing the package is light (``energy.config`` is a leaf of the config tree): import the
energy from ``energy.grasp_energy``, its terms from ``energy.terms``, per-grasp evaluation
from ``energy.per_grasp``."""
