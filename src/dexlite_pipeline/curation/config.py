"""Curation's config type: section ``curate``.

A leaf of the config tree (``settings``): it imports no curation code, so a stage's code hash
(``codehash``) covers this shape without the computation (the filters are ``curation.filters``).
"""

from __future__ import annotations

from dataclasses import dataclass

from dexlite_pipeline.config import setting
from dexlite_pipeline.energy.config import EnergyThresholds

THRESHOLDED_TERMS = ("E_fc", "E_dis", "E_pen", "penetration_mm")  # the arrays EnergyThresholds.limits() names
IMPORTED_ORIGIN = "dexgraspnet"  # ``origin`` of grasps read from a DexGraspNet import


@dataclass(frozen=True)
class CurateConfig:
    """Config section ``curate``."""

    thresholds: EnergyThresholds = setting(
        factory=EnergyThresholds, doc="keep grasps below every threshold (DexGraspNet's success criteria)")
    duplicate_translation_m: float = setting(
        0.005, "two grasps of one object and scale closer than this in palm position, ...", minimum=0)
    duplicate_rotation_deg: float = setting(10.0, "... this in palm orientation, ...", minimum=0, maximum=180)
    duplicate_joint_rad: float = setting(
        0.1, "... and this in every joint are near-duplicates: the better one is kept", minimum=0)
    max_grasps_per_object: int = setting(200, "cap per object after deduplication, best first (0 = no cap)", minimum=0)
    optimized_thresholded_terms: tuple[str, ...] = setting(
        THRESHOLDED_TERMS, "thresholds that apply to optimized grasps (all four by default; a hand whose grasps rejected by "
        "E_fc and force closure still mostly hold keeps E_dis, E_pen and penetration_mm: docs/hands.md)",
        items={"enum": THRESHOLDED_TERMS}, unique_items=True)
    imported_thresholded_terms: tuple[str, ...] = setting(
        ("E_dis",), "thresholds that also apply to imported DexGraspNet grasps (their makers filtered E_fc/E_pen with "
        "contacts and a penetration measure not stored; see curate.py)", items={"enum": THRESHOLDED_TERMS}, unique_items=True)
    energy_batch_size: int = setting(
        256, "grasps per batch when computing the energies of imported grasps", minimum=1, result_neutral=True)
    force_closure: bool = setting(
        True, "keep only grasps whose actual contacts are in force closure with friction (see curate.py): fewer curated "
        "grasps, more of which hold (measurements: docs/results.md); false: DexGraspNet's curation")
    force_closure_min_epsilon: float = setting(
        0.01, "Ferrari–Canny epsilon must exceed this: wrench resisted in every direction per N of total normal force, "
        "torques over the object scale (0 = any force closure)", minimum=0)
    force_closure_contact_distance_m: float = setting(
        0.001, "hand links this close to the object are contacts (E_dis < 5 mm over 4 contacts)", minimum=0)
    force_closure_friction: float = setting(0.6, "friction coefficient of the contact cones (the lift test's)", minimum=0)
    force_closure_cone_edges: int = setting(8, "edges of the linearized friction cones", minimum=3)

    def __post_init__(self) -> None:
        for key in ("optimized_thresholded_terms", "imported_thresholded_terms"):
            unknown = sorted(set(getattr(self, key)) - set(THRESHOLDED_TERMS))
            if unknown:
                raise ValueError(f"config.curate.{key}: unknown term(s) {', '.join(unknown)}")
        if self.max_grasps_per_object < 0:
            raise ValueError(f"config.curate.max_grasps_per_object must be >= 0, got {self.max_grasps_per_object}")
        if self.force_closure_min_epsilon < 0:
            raise ValueError(f"config.curate.force_closure_min_epsilon must be >= 0, got {self.force_closure_min_epsilon}")
