"""The ``lift`` and ``scene`` config sections: the physical constants of the MuJoCo lift and six-direction tests, and the table.

The values are pinned because each of them moves measured success rates by several
points (docs/design.md, "Physics tests"); they are echoed into every output's attributes.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from dexlite_pipeline.config import ConfigError, from_section, setting


@dataclass(frozen=True)
class LiftConfig:
    """Constants of the lift test (section ``lift`` of config.yaml)."""

    timestep_s: float = setting(0.002, "simulation step (pinned: results move with it)", exclusive_minimum=0, maximum=0.05)
    friction: float = setting(
        0.6, "sliding friction of hand and object: DexGraspBench's value for the same mass and gains; conservative (real "
        "DexGraspNet grasps at 0.6 and 1.0: docs/results.md)", minimum=0)
    object_mass_kg: float = setting(
        0.1, "every object weighs this (DexGraspBench); inertia from its convex pieces, rescaled", exclusive_minimum=0)
    finger_kp: float = setting(
        5.0, "position gain of the 22 finger actuators, N·m/rad (the gym model's 1.0 lets grasps that hold slip)", exclusive_minimum=0)
    impratio: float = setting(
        10.0, "elliptic friction cones with this impedance ratio (MuJoCo's pyramidal default lets grasps that hold slip)",
        exclusive_minimum=0)
    squeeze_rad: float = setting(0.1, "touching fingers' targets go this far past the grasp (largest joint change), rad", minimum=0)
    squeeze_contact_distance_m: float = setting(0.005, "a finger touches if one of its links is within this of the object", minimum=0)
    close_s: float = setting(0.25, "finger targets ramp from the grasp pose to the squeeze target", exclusive_minimum=0)
    hold_s: float = setting(0.25, "hold before lifting", minimum=0)
    lift_height_m: float = setting(1.0, "the hand rises this far (gravity along the object frame's -z)", exclusive_minimum=0)
    lift_s: float = setting(2.0, "... in this time, smooth cosine profile", exclusive_minimum=0)
    final_hold_s: float = setting(0.2, "hold at the top before measuring", minimum=0)
    success_lift_ratio: float = setting(0.9, "success if dz_object / dz_hand exceeds this", exclusive_minimum=0, maximum=1)
    preclose_rad: float = setting(
        0.0, "extra closure added to the four fingers' flexion-joint (J2, J1, J0) targets, rad (the lift test of the DexLite "
        "write-up (Murali): 0.07)", minimum=0)
    contact_condim: int = setting(
        3, "MuJoCo contact dimensionality of the object (3: sliding friction; 4: + torsional; 6: + torsional, rolling; the "
        "write-up's test: 6)", enum=(1, 3, 4, 6))
    max_initial_penetration_m: float = setting(
        0.002, "a grasp starting deeper in the object fails before simulation (penetration measure against the mesh, m)",
        exclusive_minimum=0)
    control_substeps: int = setting(10, "simulation steps per control update (finger targets, palm mocap)", minimum=1)
    multi_contact: bool = setting(
        True, "MuJoCo's multi-point convex contacts (its default); false: faster lift tests (~15%) that change a few outcomes "
        "(~1%; docs/results.md)")
    six_directions: bool = setting(False, "also run the six-direction test in lift_validate (evaluate has its own switch)")
    six_dir_force_per_kg_n: float = setting(
        10.0, "six-direction test: force per kg of object mass, N/kg (DexGraspBench: 10, i.e. ~1 g)", minimum=0)
    six_dir_duration_s: float = setting(
        2.0, "... applied this long along each of +x, -x, +y, -y, +z, -z (gravity off)", exclusive_minimum=0)
    six_dir_max_translation_m: float = setting(0.05, "... a direction passes if the object moves less than this", exclusive_minimum=0)
    six_dir_max_rotation_deg: float = setting(15.0, "... and rotates less than this", exclusive_minimum=0)
    six_dir_settle_factor: float = setting(
        3.0, "a direction passes before its full duration once, over the last six_dir_settle_s (and after twice that), "
        "the object has moved and turned so slowly that even this many times faster for the time left it would stay "
        "within the limits (a settled grip only creeps under a constant force); 0: always the full duration", minimum=0)
    six_dir_settle_s: float = setting(0.1, "... the window of that test, s", exclusive_minimum=0)
    six_dir_exhaustive: bool = setting(
        False, "true: test every started grasp in all six directions (per-direction diagnostics); false: only grasps that "
        "lifted, up to the first direction that fails (a held grasp's result is the same, for less CPU)")

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

    table: bool = setting(
        True, "tabletop: the object rests in its stable pose on a table no hand point may go below; false: floating objects, "
        "gravity along the object frame's -z (DexGraspNet-style, exactly the behaviour before tabletop mode)")
