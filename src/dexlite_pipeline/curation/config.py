"""Curation's config type: section ``curate``.

A leaf of the config tree (``settings``): it imports no curation code, so a stage's code hash
(``codehash``) covers this shape without the computation (the filters are ``curation.filters``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from dexlite_pipeline.energy.config import EnergyThresholds

THRESHOLDED_TERMS = ("E_fc", "E_dis", "E_pen", "penetration_mm")  # the arrays EnergyThresholds.limits() names
IMPORTED_ORIGIN = "dexgraspnet"  # ``origin`` of grasps read from a DexGraspNet import


@dataclass(frozen=True)
class CurateConfig:
    """Config section ``curate``."""

    thresholds: EnergyThresholds = field(default_factory=EnergyThresholds)  # keep grasps below every threshold
    duplicate_translation_m: float = 0.005  # palm positions closer than this ...
    duplicate_rotation_deg: float = 10.0  # ... and palm orientations closer than this ...
    duplicate_joint_rad: float = 0.1  # ... and every joint closer than this: near-duplicates
    max_grasps_per_object: int = 200  # cap per object after deduplication (0 = no cap)
    imported_thresholded_terms: tuple[str, ...] = ("E_dis",)  # thresholds applied to imported DexGraspNet grasps
    energy_batch_size: int = 256  # grasps per batch when computing energies of imported grasps
    force_closure: bool = True  # check the force closure of the actual contacts (off: DexGraspNet's curation)
    force_closure_min_epsilon: float = 0.01  # keep grasps whose Ferrari–Canny epsilon exceeds this (0: any force closure)
    force_closure_contact_distance_m: float = 0.001  # hand links this close to the object are contacts
    force_closure_friction: float = 0.6  # friction coefficient of the contacts' cones
    force_closure_cone_edges: int = 8  # edges of the linearized friction cones

    def __post_init__(self) -> None:
        unknown = sorted(set(self.imported_thresholded_terms) - set(THRESHOLDED_TERMS))
        if unknown:
            raise ValueError(f"config.curate.imported_thresholded_terms: unknown term(s) {', '.join(unknown)}")
        if self.max_grasps_per_object < 0:
            raise ValueError(f"config.curate.max_grasps_per_object must be >= 0, got {self.max_grasps_per_object}")
        if self.force_closure_min_epsilon < 0:
            raise ValueError(f"config.curate.force_closure_min_epsilon must be >= 0, got {self.force_closure_min_epsilon}")
