"""Curation: which synthesized or imported grasps become training data (energy thresholds,
object checks, force closure of the actual contacts, near-duplicates, a cap per object)."""
