"""The energy's config types: section ``energy``, the term weights and the energy thresholds.

A leaf of the config tree (``settings``): it imports no energy code, so a stage's code hash
(``codehash``) covers these shapes without the computation. ``EnergyThresholds`` is the one type
for every place that thresholds energies: optimization from scratch marks ``passes_energy_thresholds`` with
it (``optimize_grasps.thresholds``) and curation filters with it (``curate.thresholds``).
"""

from __future__ import annotations

from dataclasses import dataclass

from dexlite_pipeline.config import setting

# Mean spacing (m) of the object points of the judged penetration depth: every check of whether a grasp starts
# inside its object (the energy filter, the optimizers' reported depth and contact resolution, the lift test's
# start check) samples this densely, whatever spacing the energy's own E_pen uses (``object_point_spacing_m``).
JUDGED_POINT_SPACING_M = 0.002

# DexGraspNet's success criteria: a grasp passes when each term is below its value (E_dis, E_pen in metres).
DEXGRASPNET_THRESHOLDS: dict[str, float] = {"E_fc": 0.3, "E_dis": 0.005, "E_pen": 0.001}


@dataclass(frozen=True)
class EnergyThresholds:
    """A grasp passes when each term is below its threshold: E_fc (unitless), E_dis and E_pen (metres)."""

    max_e_fc: float = setting(DEXGRASPNET_THRESHOLDS["E_fc"], "force closure E_fc (DexGraspNet: 0.3)", exclusive_minimum=0)
    max_e_dis_m: float = setting(DEXGRASPNET_THRESHOLDS["E_dis"], "contact distance E_dis, metres (DexGraspNet: 5 mm)", exclusive_minimum=0)
    max_e_pen_m: float = setting(DEXGRASPNET_THRESHOLDS["E_pen"], "penetration E_pen, metres (DexGraspNet: 1 mm)", exclusive_minimum=0)
    max_penetration_m: float = setting(0.002, "penetration depth against the mesh, metres (the lift test's start cap)", exclusive_minimum=0)

    def __post_init__(self) -> None:
        for name in ("max_e_fc", "max_e_dis_m", "max_e_pen_m", "max_penetration_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"thresholds.{name} must be positive, got {getattr(self, name)}")

    def limits(self) -> dict[str, float]:
        """Array name -> threshold: E_fc, E_dis, E_pen and the penetration depth ``penetration_mm`` (in mm, as stored)."""
        return {"E_fc": self.max_e_fc, "E_dis": self.max_e_dis_m, "E_pen": self.max_e_pen_m, "penetration_mm": self.max_penetration_m * 1000.0}

    def passes(self, terms: dict) -> "numpy.ndarray":
        """(B,) bool: every thresholded array of ``terms`` (arrays by name, ``limits``) is below its limit.

        The depth passes at exactly the cap (≤, as the lift test's start check); the energies below it.
        """
        import numpy as np  # here, not at the top: the config tree is read while the workflow parses (no numpy)

        passing = None
        for name, limit in self.limits().items():
            values = np.asarray(terms[name])
            below = values <= limit if name == "penetration_mm" else values < limit
            passing = below if passing is None else passing & below
        return passing


@dataclass(frozen=True)
class EnergyWeights:
    """Weights of the terms in the total energy (defaults: DexGraspNet's and E_post's)."""

    fc: float = setting(1.0, "force closure ‖Σn‖² + ‖Σx×n‖²", minimum=0)
    dis: float = setting(100.0, "contact distance Σ|d| (metres)", minimum=0)
    pen: float = setting(100.0, "penetration depth sums, both ways (metres)", minimum=0)
    spen: float = setting(10.0, "self-penetration of keypoint pairs (metres)", minimum=0)
    joints: float = setting(1.0, "joint-limit violation (radians)", minimum=0)
    # E_table is a term of its own, never in ``combined_energy``'s five
    table: float = setting(100.0, "depth of hand surface points below the table (metres; tabletop mode only)", minimum=0)


@dataclass(frozen=True)
class EnergyConfig:
    """Config section ``energy``: term weights and how the terms are sampled."""

    weights: EnergyWeights = setting(
        factory=EnergyWeights, doc="E = fc·E_fc + dis·E_dis + pen·E_pen + spen·E_spen + joints·E_joints (+ table·E_table on a table)")
    object_point_spacing_m: float = setting(
        0.004, "mean spacing of E_pen's object surface points at the grasp's scale, m (per area, not per object; the judged depth "
        "of every check samples at 2 mm)", exclusive_minimum=0)
    self_penetration_margin_m: float = setting(0.02, "keypoint pairs closer than this are penalized (E_spen of every stage)", minimum=0)
