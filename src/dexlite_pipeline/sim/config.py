"""The ``lift`` and ``scene`` config sections: the physical constants of the MuJoCo lift and six-direction tests, and the table.

The values are pinned because each of them moves measured success rates by several
points (docs/design.md, "Physics tests"); they are echoed into every output's attributes.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from dexlite_pipeline.config import ConfigError, from_section


@dataclass(frozen=True)
class LiftConfig:
    """Constants of the lift test (section ``lift`` of config.yaml)."""

    timestep_s: float = 0.002  # MuJoCo step
    friction: float = 0.6  # sliding friction of hand and object geoms (DexGraspBench's value)
    object_mass_kg: float = 0.1  # object mass (DexGraspBench); inertia scaled to match
    finger_kp: float = 5.0  # position gain of the 22 finger actuators, N·m/rad
    impratio: float = 10.0  # frictional-to-normal impedance ratio (elliptic cones)
    squeeze_rad: float = 0.1  # largest joint change of a touching finger's squeeze target
    squeeze_contact_distance_m: float = 0.005  # a finger touches if one of its links is this close
    close_s: float = 0.25  # ramp of the finger targets from grasp pose to squeeze target
    hold_s: float = 0.25  # hold before lifting
    lift_height_m: float = 1.0  # hand rise
    lift_s: float = 2.0  # duration of the rise (smooth profile)
    final_hold_s: float = 0.2  # hold at the top
    success_lift_ratio: float = 0.9  # success if dz_object / dz_hand is above this
    preclose_rad: float = 0.0  # added to the finger flexion joints' (J2, J1, J0) closing targets, rad (the lift test of the DexLite write-up (Murali): 0.07)
    contact_condim: int = 3  # MuJoCo contact dimensionality of the object's geoms: 3 sliding friction, 4 + torsional,
    # 6 + rolling (the write-up's test: 6)
    max_initial_penetration_m: float = 0.002  # a grasp starting deeper in the object (penetration measure, m) fails before simulation
    control_substeps: int = 10  # simulation steps per control update (targets and mocap)
    multi_contact: bool = True  # MuJoCo's multi-point convex contacts (its default); off: ~15% faster, ~1% of outcomes change
    six_directions: bool = False  # also run the six-direction test
    six_dir_force_per_kg_n: float = 10.0  # external force per kg of object mass (DexGraspBench: 10 N/kg)
    six_dir_duration_s: float = 2.0  # force applied this long in each direction
    six_dir_max_translation_m: float = 0.05  # allowed object displacement
    six_dir_max_rotation_deg: float = 15.0  # allowed object rotation
    six_dir_exhaustive: bool = False  # every started grasp, all six directions (per-direction diagnostics); False: only
    # grasps that lifted, up to the first direction that fails (a held grasp's pass or fail is the same, for less CPU)

    def __post_init__(self) -> None:
        positive = (
            "timestep_s", "object_mass_kg", "finger_kp", "impratio", "close_s", "lift_height_m", "lift_s",
            "max_initial_penetration_m", "six_dir_duration_s", "six_dir_max_translation_m", "six_dir_max_rotation_deg",
        )  # fmt: skip
        for name in positive:
            if not getattr(self, name) > 0:
                raise ConfigError(f"lift.{name} must be positive, got {getattr(self, name)}")
        for name in ("friction", "squeeze_rad", "squeeze_contact_distance_m", "hold_s", "final_hold_s", "six_dir_force_per_kg_n"):
            if getattr(self, name) < 0:
                raise ConfigError(f"lift.{name} must be non-negative, got {getattr(self, name)}")
        if not 0 < self.success_lift_ratio <= 1:
            raise ConfigError(f"lift.success_lift_ratio must be in (0, 1], got {self.success_lift_ratio}")
        if self.contact_condim not in (1, 3, 4, 6):
            raise ConfigError(f"lift.contact_condim must be one of 1, 3, 4, 6, got {self.contact_condim}")
        if self.preclose_rad < 0:
            raise ConfigError(f"lift.preclose_rad must be non-negative, got {self.preclose_rad}")
        if self.control_substeps < 1:
            raise ConfigError(f"lift.control_substeps must be >= 1, got {self.control_substeps}")

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)

    def steps(self, seconds: float) -> int:
        """Simulation steps covering ``seconds`` (nearest whole step)."""
        return int(round(seconds / self.timestep_s))

    def chunks(self, seconds: float) -> list[int]:
        """``seconds`` as control chunks of ``control_substeps`` steps (the last one shorter if need be)."""
        total, chunk = self.steps(seconds), self.control_substeps
        return [chunk] * (total // chunk) + ([total % chunk] if total % chunk else [])


def lift_config_from(config: dict | None, **overrides) -> LiftConfig:
    """LiftConfig from a config mapping's ``lift`` section (defaults where absent), with overrides."""
    section = dict((config or {}).get("lift") or {})
    section.update({k: v for k, v in overrides.items() if v is not None})
    return from_section(LiftConfig, section, "config.lift")


@dataclass(frozen=True)
class SceneConfig:
    """Config section ``scene``: whether the object stands on a table (tabletop) or floats (DexGraspNet-style)."""

    table: bool = True  # tabletop mode; false: floating objects, exactly the behaviour before tabletop mode
