"""Grasp energies (force closure, contact distance, penetration, self-penetration, joint limits)."""
